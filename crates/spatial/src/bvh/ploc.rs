//! Bottom-up BVH construction by locally-ordered clustering (PLOC: D. Meister and J. Bittner,
//! "Parallel Locally-Ordered Clustering for Bounding Volume Hierarchy Construction", IEEE
//! TVCG 2018), written so that every build finishes in O(n log n) whatever the input.
//!
//! The algorithm: sort the primitives along a Morton curve (63-bit codes of their box
//! centres), then repeat passes until one cluster is left. In a pass every cluster looks at
//! the `r` clusters before and after it in the sorted list and picks the neighbour whose union
//! with it has the smallest surface area; two clusters that pick each other merge into a new
//! inner node, which takes their place in the list. The result is handed to `obvhs` as a
//! [`Bvh2`] (same node layout as its own PLOC builder), so its reinsertion optimizer and leaf
//! collapser run on it unchanged.
//!
//! Why not `obvhs`'s own PLOC builder: it breaks ties between equal costs by taking the
//! *last* candidate scanned, so in a run of clusters whose pairwise costs are equal every
//! cluster points to the right and only the rightmost pair of the run is mutual. Each pass
//! then merges about one pair per run, so a run of n clusters needs O(n) passes of O(n) work:
//! n coincident boxes take n - 1 passes and come out as a chain of depth n, and a row of n
//! equally spaced identical boxes takes n / 2 passes (the tree stays shallow there, the time
//! is still quadratic). Two changes make the build robust:
//!
//! 1. **A strict order on pairs.** Candidate pairs `(a, b)` (`a < b`, positions in the current
//!    list) are ordered by cost, then by distance `b - a`, then by preferring an even `a`, then
//!    by `a`. The order is total and the same seen from both ends of a pair, so the globally
//!    cheapest pair is always mutual, and among equal costs the adjacent pairs (0,1), (2,3), …
//!    win: n coincident boxes pair up perfectly and build a balanced tree in log2(n) passes.
//! 2. **A progress guarantee.** Strict costs can still chain (gaps shrinking along a row make
//!    every cluster's nearest neighbour its right one). When a pass pairs fewer than
//!    1/[`SLOW_PASS`] of the clusters, it instead pairs the clusters greedily in list order,
//!    each with the neighbour it picked if that one is still free. Each cluster is picked by at
//!    most `2r` others, so at least 1/(2r + 1) of the clusters are paired: every pass removes a
//!    fixed fraction of the clusters, there are O(r log n) passes, and the work, O(r) per
//!    cluster per pass, sums to O(r² n) after the O(n log n) sort.
//!
//! Sorting is by (code, primitive index), so the result depends only on the input: no
//! randomness, and the same tree for any thread count (only the sort runs in parallel).

use glam::DVec3;
use obvhs::aabb::Aabb as ObAabb;
use obvhs::bvh2::{node::Bvh2Node, Bvh2, DEFAULT_MAX_STACK_DEPTH};
use obvhs::ploc::{morton::morton_encode_u64, PlocSearchDistance};

/// A pass that pairs fewer than `1 / SLOW_PASS` of its clusters is redone by greedy pairing.
/// Ordinary input pairs over a quarter of its clusters in every pass (the default city's
/// meshes and instances, random boxes, at every search radius), so it never takes the
/// fallback.
const SLOW_PASS: usize = 16;

/// Largest coordinate on each axis of the 21-bit Morton grid.
const GRID_MAX: f64 = ((1u32 << 21) - 1) as f64;

/// No partner this pass.
const NONE: u32 = u32::MAX;

/// What a build did, for tests and reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct PlocStats {
    /// Clustering passes.
    pub passes: usize,
    /// Passes that fell back to greedy pairing.
    pub greedy_passes: usize,
}

/// Builds a binary BVH over `boxes` (all finite), one primitive per leaf: leaf `first_index`
/// is the primitive's index in `boxes`, `primitive_indices` is the identity. Passes before
/// `full_search_from` look at adjacent clusters only (as `obvhs`'s `search_depth_threshold`).
pub(crate) fn build(boxes: &[ObAabb], search: PlocSearchDistance, full_search_from: usize) -> (Bvh2, PlocStats) {
    match search {
        PlocSearchDistance::Minimum => build_with::<1>(boxes, full_search_from),
        PlocSearchDistance::VeryLow => build_with::<2>(boxes, full_search_from),
        PlocSearchDistance::Low => build_with::<6>(boxes, full_search_from),
        PlocSearchDistance::Medium => build_with::<14>(boxes, full_search_from),
        PlocSearchDistance::High => build_with::<24>(boxes, full_search_from),
        PlocSearchDistance::VeryHigh => build_with::<32>(boxes, full_search_from),
    }
}

fn build_with<const R: usize>(boxes: &[ObAabb], full_search_from: usize) -> (Bvh2, PlocStats) {
    let n = boxes.len();
    let mut bvh = Bvh2 {
        primitive_indices: (0..n as u32).collect(),
        children_are_ordered_after_parents: true,
        ..Default::default()
    };
    let mut stats = PlocStats::default();
    if n == 0 {
        return (bvh, stats);
    }
    let mut cur = morton_sorted_leaves(boxes);
    let mut next: Vec<Bvh2Node> = Vec::with_capacity(n);
    let mut target = vec![0i8; n];
    let mut partner = vec![NONE; n];
    bvh.nodes = vec![Bvh2Node::default(); 2 * n - 1];
    // Children are written from the end of the array down, pair by pair, so every child
    // comes after its parent.
    let mut insert = bvh.nodes.len();
    while cur.len() > 1 {
        let count = cur.len();
        if R == 1 || stats.passes < full_search_from {
            pick_adjacent(&cur, &mut target[..count]);
        } else {
            pick_within::<R>(&cur, &mut target[..count]);
        }
        if !pair_mutual(&target[..count], &mut partner[..count]) {
            pair_greedy(&target[..count], &mut partner[..count]);
            stats.greedy_passes += 1;
        }
        next.clear();
        for (i, &p) in partner[..count].iter().enumerate() {
            if p == NONE {
                next.push(cur[i]);
            } else if (p as usize) < i {
                let (left, right) = (cur[p as usize], cur[i]);
                insert -= 2;
                bvh.nodes[insert] = left;
                bvh.nodes[insert + 1] = right;
                next.push(Bvh2Node::new(left.aabb().union(right.aabb()), 0, insert as u32));
            }
        }
        std::mem::swap(&mut cur, &mut next);
        stats.passes += 1;
    }
    debug_assert!(insert == 1 || n == 1);
    bvh.nodes[0] = cur[0];
    // Every pass adds at most one level, so this bounds the depth (what obvhs sizes its
    // traversal stacks by).
    bvh.max_depth = DEFAULT_MAX_STACK_DEPTH.max(stats.passes + 1);
    (bvh, stats)
}

/// One leaf per primitive, sorted by the Morton code of its box centre, ties by index.
fn morton_sorted_leaves(boxes: &[ObAabb]) -> Vec<Bvh2Node> {
    morton_order(boxes).iter().map(|&i| Bvh2Node::new(boxes[i as usize], 1, i)).collect()
}

/// The primitive indices sorted by the Morton code of their box centres (63-bit codes on the
/// centres' bounding box), ties by index. Codes and sort run in parallel; the keys are
/// unique, so the order does not depend on the thread count.
pub(crate) fn morton_order(boxes: &[ObAabb]) -> Vec<u32> {
    morton_keys(boxes).into_iter().map(|(_, i)| i).collect()
}

/// [`morton_order`] with each primitive's code: `(code, index)`, sorted.
pub(crate) fn morton_keys(boxes: &[ObAabb]) -> Vec<(u64, u32)> {
    use rayon::prelude::*;
    let center = |b: &ObAabb| (b.min.as_dvec3() + b.max.as_dvec3()) * 0.5;
    let (lo, hi) = boxes
        .par_iter()
        .fold(
            || (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), b| (lo.min(center(b)), hi.max(center(b))),
        )
        .reduce(|| (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    let extent = hi - lo;
    // A flat axis (every centre equal on it) contributes nothing rather than dividing by zero.
    let scale = DVec3::select(extent.cmpgt(DVec3::ZERO), GRID_MAX / extent, DVec3::ZERO);
    let mut keys: Vec<(u64, u32)> = boxes
        .par_iter()
        .enumerate()
        .map(|(i, b)| {
            let g = ((center(b) - lo) * scale).clamp(DVec3::ZERO, DVec3::splat(GRID_MAX));
            // `as` maps NaN to 0, so a malformed box cannot panic here.
            (morton_encode_u64(g.x as u32, g.y as u32, g.z as u32), i as u32)
        })
        .collect();
    keys.par_sort_unstable();
    keys
}

/// The cost of merging two clusters: the half surface area of their union (NaN, from boxes
/// whose extent overflows, counts as infinite so that comparisons stay meaningful).
#[inline(always)]
fn merge_cost(a: &ObAabb, b: &ObAabb) -> f32 {
    a.union(b).half_area().min(f32::INFINITY)
}

/// The rank of candidate pair `(a, b)` (`a < b`) as seen from one of its ends, smaller first:
/// cost, then distance `b - a`, then an even `a`, then the smaller `a`. The order is strict
/// and does not depend on which end looks, so the cheapest pair overall is always mutual.
/// Costs are never negative (NaN was made infinite), so their bits order like their values;
/// `right` (the candidate is `b`) ranks the smaller `a` first at equal parity.
#[inline(always)]
fn rank(cost: f32, dist: usize, a: usize, right: bool) -> u64 {
    (cost.to_bits() as u64) << 32 | ((dist as u64) << 2) | ((a as u64 & 1) << 1) | right as u64
}

/// The offset a rank names (its candidate relative to the cluster that ranked it).
#[inline(always)]
fn offset(rank: u64) -> i8 {
    let dist = (rank as u32 >> 2) as i8;
    if rank & 1 == 1 {
        dist
    } else {
        -dist
    }
}

/// Each cluster's choice between its two adjacent clusters (radius 1): -1 or +1.
fn pick_adjacent(cur: &[Bvh2Node], target: &mut [i8]) {
    let count = cur.len();
    let mut left = u64::MAX; // rank of (i - 1, i) seen from i
    for i in 0..count {
        let mut best = left;
        left = u64::MAX;
        if i + 1 < count {
            let cost = merge_cost(cur[i].aabb(), cur[i + 1].aabb());
            best = best.min(rank(cost, 1, i, true));
            left = rank(cost, 1, i, false);
        }
        target[i] = offset(best);
    }
}

/// Each cluster's cheapest neighbour within `R` positions, as an offset. Costs are symmetric,
/// so a cluster computes the costs to the clusters after it and leaves them in a ring for
/// those clusters to read (`ring[i % R][j % R]` is the cost of `(i, j)`, `i < j <= i + R`).
fn pick_within<const R: usize>(cur: &[Bvh2Node], target: &mut [i8]) {
    let count = cur.len();
    let mut ring = [[0f32; R]; R];
    for i in 0..count {
        let (lo, hi) = (i.saturating_sub(R), (i + R + 1).min(count));
        let mut best = u64::MAX;
        for j in lo..i {
            best = best.min(rank(ring[j % R][i % R], i - j, j, false));
        }
        let own = *cur[i].aabb();
        for j in i + 1..hi {
            let cost = merge_cost(&own, cur[j].aabb());
            ring[i % R][j % R] = cost;
            best = best.min(rank(cost, j - i, i, true));
        }
        target[i] = offset(best);
    }
}

#[inline(always)]
fn picked(target: &[i8], i: usize) -> usize {
    (i as isize + target[i] as isize) as usize
}

/// Pairs the clusters that picked each other; false (partners undefined) when that pairs
/// fewer than `1 / SLOW_PASS` of them.
fn pair_mutual(target: &[i8], partner: &mut [u32]) -> bool {
    let mut paired = 0;
    for (i, p) in partner.iter_mut().enumerate() {
        let j = picked(target, i);
        *p = if picked(target, j) == i {
            paired += 1;
            j as u32
        } else {
            NONE
        };
    }
    paired * SLOW_PASS >= target.len()
}

/// Pairs the clusters in list order, each with the one it picked if that one is still free.
fn pair_greedy(target: &[i8], partner: &mut [u32]) {
    partner.fill(NONE);
    for i in 0..target.len() {
        if partner[i] == NONE {
            let j = picked(target, i);
            if partner[j] == NONE {
                partner[i] = j as u32;
                partner[j] = i as u32;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    fn depth(b: &Bvh2) -> usize {
        let mut stack = vec![(0usize, 1usize)];
        let mut max = 0;
        while let Some((i, d)) = stack.pop() {
            max = max.max(d);
            let node = &b.nodes[i];
            if !node.is_leaf() {
                stack.push((node.first_index as usize, d + 1));
                stack.push((node.first_index as usize + 1, d + 1));
            }
        }
        max
    }

    /// Every primitive in exactly one leaf, children inside parents and after them.
    fn check(b: &Bvh2, boxes: &[ObAabb]) {
        let mut seen = vec![false; boxes.len()];
        for (i, node) in b.nodes.iter().enumerate() {
            if node.is_leaf() {
                let p = b.primitive_indices[node.first_index as usize] as usize;
                assert!(!std::mem::replace(&mut seen[p], true), "primitive {p} twice");
                assert_eq!(*node.aabb(), boxes[p]);
            } else {
                let c = node.first_index as usize;
                assert!(c > i && c + 1 < b.nodes.len());
                for k in [c, c + 1] {
                    let u = node.aabb().union(b.nodes[k].aabb());
                    assert_eq!(u, *node.aabb(), "node {i} does not contain child {k}");
                }
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    fn log2(n: usize) -> usize {
        n.next_power_of_two().trailing_zeros() as usize
    }

    const SEARCHES: [PlocSearchDistance; 4] = [
        PlocSearchDistance::Minimum,
        PlocSearchDistance::Low,
        PlocSearchDistance::Medium,
        PlocSearchDistance::VeryHigh,
    ];

    #[test]
    fn coincident_boxes_build_a_balanced_tree() {
        let b = ObAabb::new(Vec3A::ZERO, Vec3A::new(1.0, 1.0, 0.0));
        for n in [1, 2, 3, 1000, 20_000] {
            let boxes = vec![b; n];
            for s in SEARCHES {
                let (bvh, stats) = build(&boxes, s, 2);
                check(&bvh, &boxes);
                assert_eq!(depth(&bvh), log2(n) + 1, "{n} coincident, {s:?}");
                assert_eq!(stats.greedy_passes, 0);
            }
        }
    }

    #[test]
    fn equally_spaced_rows_take_logarithmically_many_passes() {
        // obvhs's tie rule needs one pass per box here.
        let boxes: Vec<ObAabb> = (0..20_000)
            .map(|i| ObAabb::new(Vec3A::new(i as f32, 0.0, 0.0), Vec3A::new(i as f32 + 0.5, 0.5, 0.5)))
            .collect();
        for s in SEARCHES {
            let (bvh, stats) = build(&boxes, s, 2);
            check(&bvh, &boxes);
            assert!(stats.passes <= 2 * log2(boxes.len()), "{s:?}: {stats:?}");
        }
    }

    #[test]
    fn shrinking_gaps_fall_back_to_greedy_pairing() {
        // Gaps shrink left to right: every box's nearest neighbour is its right one, so only
        // the last pair is mutual. Integer coordinates keep the costs exact.
        let n = 2000;
        let mut x = 0.0f32;
        let boxes: Vec<ObAabb> = (0..n)
            .map(|i| {
                x += (2 * n - i) as f32;
                ObAabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + 1.0, 1.0, 1.0))
            })
            .collect();
        for s in SEARCHES {
            let (bvh, stats) = build(&boxes, s, 0);
            check(&bvh, &boxes);
            assert!(stats.greedy_passes > 0, "{s:?}: {stats:?}");
            assert!(stats.passes <= 5 * log2(n), "{s:?}: {stats:?}");
        }
    }

    #[test]
    fn builds_are_deterministic_and_mixed_input_is_fine() {
        let mut boxes = vec![ObAabb::new(Vec3A::splat(3.0), Vec3A::splat(4.0)); 5000];
        let mut h = 12345u64;
        for _ in 0..5000 {
            h = h.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let p = Vec3A::new((h >> 40) as f32 / 1e4, (h >> 20 & 0xfff) as f32 / 1e2, (h & 0xfff) as f32 / 1e2);
            boxes.push(ObAabb::new(p, p + 0.25));
        }
        for s in SEARCHES {
            let (a, stats) = build(&boxes, s, 2);
            check(&a, &boxes);
            assert!(depth(&a) <= 3 * log2(boxes.len()), "{s:?}: depth {}", depth(&a));
            assert!(stats.passes <= 5 * log2(boxes.len()) && stats.greedy_passes == 0, "{s:?}: {stats:?}");
            let (b, _) = build(&boxes, s, 2);
            assert!(a.nodes.iter().zip(&b.nodes).all(|(x, y)| x.aabb() == y.aabb() && x.first_index == y.first_index));
        }
    }
}

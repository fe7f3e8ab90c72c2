//! Parallel builds of large wide BVHs: the primitives are sorted along a Morton curve, cut
//! into [`WIDTH`] runs of about equal size, a tree is built over each run on its own thread,
//! and the four trees become the four children of one root.
//!
//! Each cut is moved (by at most an eighth of the input) to the boundary of the coarsest
//! octree cell it can reach, so the runs are unions of whole cells with compact boxes (cuts
//! at exact quarters left boxes that overlapped and slowed aerial views by about 12%); the
//! forced top split then costs little: it is the top split of a linear BVH (Lauterbach et al.
//! 2009, "Fast BVH Construction on GPUs"), below which each run gets the full PLOC,
//! reinsertion and collapse of a serial build. The cut depends only on the input, never on
//! the thread count, so every thread count builds the same tree.

use obvhs::aabb::Aabb as ObAabb;
use rayon::prelude::*;

use super::{Ploc, WideBuildParams, WideBvh, WideChild, WideNode, WIDTH};

/// Smallest input built in parallel runs (PLOC builds: the TLAS); below it one serial build
/// is fast enough, and small instance trees keep their serial shape.
pub(crate) const SPLIT_MIN: usize = 1 << 17;

/// Builds over `boxes` as [`WIDTH`] Morton runs in parallel by PLOC (settings `ploc`),
/// joined under one root.
pub(crate) fn build_split(boxes: &[ObAabb], params: WideBuildParams, ploc: Ploc) -> WideBvh {
    let keys = crate::bvh::ploc::morton_keys(boxes);
    let order: Vec<u32> = keys.iter().map(|k| k.1).collect();
    let mut bounds = vec![0];
    for k in 1..WIDTH {
        let cut = cell_cut(&keys, k * keys.len() / WIDTH, keys.len() / (2 * WIDTH));
        bounds.push(cut.max(*bounds.last().unwrap_or(&0)));
    }
    bounds.push(keys.len());
    let runs: Vec<&[u32]> = bounds.windows(2).map(|w| &order[w[0]..w[1]]).collect();
    let parts: Vec<WideBvh> = runs
        .into_par_iter()
        .map(|ids| {
            let sub: Vec<ObAabb> = ids.iter().map(|&i| boxes[i as usize]).collect();
            let mut t = WideBvh::build_serial(&sub, params, ploc);
            for o in &mut t.order {
                *o = ids[*o as usize];
            }
            t
        })
        .collect();
    join(parts)
}

/// A cut near position `target` of the sorted `keys` that falls on the boundary of an
/// octree cell as coarse as possible (the same leading code bits on each side form whole
/// cells), within `slack` positions of the target: runs of whole cells have compact,
/// barely overlapping boxes, where a cut in the middle of a cell would leave two runs whose
/// boxes both span it.
fn cell_cut(keys: &[(u64, u32)], target: usize, slack: usize) -> usize {
    let Some(&(code, _)) = keys.get(target) else { return keys.len() };
    // Codes have 63 bits, three per octree level.
    for level in 1..=21 {
        let shift = 63 - 3 * level;
        let cell = code >> shift;
        let lo = keys.partition_point(|k| k.0 >> shift < cell);
        let hi = keys.partition_point(|k| k.0 >> shift <= cell);
        let best = if target - lo <= hi - target { lo } else { hi };
        if best.abs_diff(target) <= slack {
            return best;
        }
    }
    target
}

/// The trees of `parts` (at most [`WIDTH`], each over its own primitives) as the children
/// of one new root; the root comes first, then each part's nodes in turn (parents before
/// children).
fn join(parts: Vec<WideBvh>) -> WideBvh {
    debug_assert!(parts.len() <= WIDTH);
    let mut root = WideNode::EMPTY;
    let mut nodes = vec![WideNode::EMPTY];
    let mut order = Vec::with_capacity(parts.iter().map(|p| p.order.len()).sum());
    let mut depth = 0;
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for (k, p) in parts.into_iter().enumerate() {
        let (node_base, prim_base) = (nodes.len() as u32, order.len() as u32);
        let mut r = p.root;
        if r.is_empty() {
            continue;
        }
        r.link = super::shift_link(r.link, r.count, node_base, prim_base);
        root.set(k, &r);
        for a in 0..3 {
            lo[a] = lo[a].min(r.lo[a]);
            hi[a] = hi[a].max(r.hi[a]);
        }
        nodes.extend(p.nodes.iter().map(|n| n.shifted(node_base, prim_base)));
        order.extend_from_slice(&p.order);
        depth = depth.max(p.depth);
    }
    nodes[0] = root;
    WideBvh { root: WideChild { lo, link: 0, hi, count: 0 }, nodes, order, depth: depth + 1 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::wide::{Builder, EMPTY_LINK};
    use glam::Vec3A;

    /// A split PLOC build with the BLAS settings.
    fn blas_split(boxes: &[ObAabb]) -> WideBvh {
        let params = WideBuildParams::BLAS_PLOC;
        let Builder::Ploc(ploc) = params.builder else { unreachable!("BLAS_PLOC builds by PLOC") };
        build_split(boxes, params, ploc)
    }

    #[test]
    fn split_builds_are_valid_and_thread_independent() {
        let n = 50_000;
        let mut h = 99u64;
        let boxes: Vec<ObAabb> = (0..n)
            .map(|_| {
                h = h.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let p = Vec3A::new((h >> 40) as f32 / 1e3, (h >> 20 & 0xfff) as f32 / 1e2, (h & 0xfff) as f32 / 1e2);
                ObAabb::new(p, p + 0.5)
            })
            .collect();
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let a = one.install(|| blas_split(&boxes));
        let b = two.install(|| blas_split(&boxes));
        a.validate(n).unwrap();
        assert_eq!(a.order, b.order);
        assert_eq!(a.nodes.len(), b.nodes.len());
        assert!(a.nodes.iter().zip(&b.nodes).all(|(x, y)| x.lo == y.lo && x.hi == y.hi && x.link == y.link));
        // Four runs under the root.
        let root = &a.nodes[0];
        assert!((0..WIDTH).all(|k| root.link[k] != EMPTY_LINK));
        // Cuts land on the coarsest cell boundary within the slack.
        let keys: Vec<(u64, u32)> = (0..100u32).map(|i| (((i / 30) as u64) << 60 | i as u64, i)).collect();
        assert_eq!(cell_cut(&keys, 25, 10), 30);
        assert_eq!(cell_cut(&keys, 50, 10), 60);
        assert_eq!(cell_cut(&keys, 50, 3), 48); // cells of 8 at the finer levels
        assert_eq!(cell_cut(&keys, 50, 1), 50);
        // Fewer than four primitives: some runs empty, still valid.
        for m in [1usize, 2, 3, 5] {
            blas_split(&boxes[..m]).validate(m).unwrap();
        }
    }
}

//! Parallel builds of large wide BVHs: the primitives are sorted along a Morton curve, cut
//! into [`WIDTH`] runs of equal size, a tree is built over each run on its own thread, and
//! the four trees become the four children of one root.
//!
//! Runs of a Morton order are spatially compact (each is a union of few octree cells), so
//! the forced top split costs little: it is the top split of a linear BVH (Lauterbach et al.
//! 2009, "Fast BVH Construction on GPUs"), below which each run gets the full PLOC,
//! reinsertion and collapse of a serial build. The cut depends only on the input, never on
//! the thread count, so every thread count builds the same tree.

use obvhs::aabb::Aabb as ObAabb;
use rayon::prelude::*;

use super::{WideBuildParams, WideBvh, WideChild, WideNode, EMPTY_LINK, WIDTH};

/// Smallest input built in parallel runs; below it one serial build is fast enough (and
/// small trees, such as the instanced city's building meshes, keep their serial shape).
pub(crate) const SPLIT_MIN: usize = 1 << 17;

/// Builds over `boxes` as [`WIDTH`] Morton runs in parallel, joined under one root.
pub(crate) fn build_split(boxes: &[ObAabb], params: WideBuildParams) -> WideBvh {
    let order = crate::bvh::ploc::morton_order(boxes);
    let run = order.len().div_ceil(WIDTH).max(1);
    let parts: Vec<WideBvh> = order
        .par_chunks(run)
        .map(|ids| {
            let sub: Vec<ObAabb> = ids.iter().map(|&i| boxes[i as usize]).collect();
            let mut t = WideBvh::build_serial(&sub, params);
            for o in &mut t.order {
                *o = ids[*o as usize];
            }
            t
        })
        .collect();
    join(parts)
}

/// The trees of `parts` (at most [`WIDTH`], each over its own primitives) as the children
/// of one new root; the root comes first, then each part's nodes in turn (depth first).
fn join(parts: Vec<WideBvh>) -> WideBvh {
    debug_assert!(parts.len() <= WIDTH);
    let mut root = WideNode::EMPTY;
    let mut nodes = vec![WideNode::EMPTY];
    let mut order = Vec::with_capacity(parts.iter().map(|p| p.order.len()).sum());
    let mut depth = 0;
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for (k, p) in parts.into_iter().enumerate() {
        let (node_base, prim_base) = (nodes.len() as u32, order.len() as u32);
        let shift = |link: u32, count: u32| match (link, count) {
            (EMPTY_LINK, _) => EMPTY_LINK,
            (l, 0) => l + node_base,
            (l, _) => l + prim_base,
        };
        let mut r = p.root;
        if r.is_empty() {
            continue;
        }
        r.link = shift(r.link, r.count);
        root.set(k, &r);
        for a in 0..3 {
            lo[a] = lo[a].min(r.lo[a]);
            hi[a] = hi[a].max(r.hi[a]);
        }
        nodes.extend(p.nodes.iter().map(|n| {
            let mut n = *n;
            for s in 0..WIDTH {
                n.link[s] = shift(n.link[s], n.count[s]);
            }
            n
        }));
        order.extend_from_slice(&p.order);
        depth = depth.max(p.depth);
    }
    nodes[0] = root;
    WideBvh { root: WideChild { lo, link: 0, hi, count: 0 }, nodes, order, depth: depth + 1 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

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
        let a = one.install(|| build_split(&boxes, WideBuildParams::BLAS));
        let b = two.install(|| build_split(&boxes, WideBuildParams::BLAS));
        a.validate(n).unwrap();
        assert_eq!(a.order, b.order);
        assert_eq!(a.nodes.len(), b.nodes.len());
        assert!(a.nodes.iter().zip(&b.nodes).all(|(x, y)| x.lo == y.lo && x.hi == y.hi && x.link == y.link));
        // Four runs under the root, each a quarter of the primitives.
        let root = &a.nodes[0];
        assert!((0..WIDTH).all(|k| root.link[k] != EMPTY_LINK));
        // Fewer than four primitives: some runs empty, still valid.
        for m in [1usize, 2, 3, 5] {
            build_split(&boxes[..m], WideBuildParams::BLAS).validate(m).unwrap();
        }
    }
}

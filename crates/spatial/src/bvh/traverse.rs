//! BVH frustum culling (plane masking, plane coherency), and counting what is in the
//! frustum without listing it.
//!
//! Culling follows Assarsson & Möller 2000 (see [`crate::Frustum`]): a node fully inside a
//! plane clears that plane's mask bit for its subtree, and a node fully inside every plane
//! reports its whole subtree `inside` without further tests. The front-to-back traversal is
//! in [`super::front_to_back`].

use super::Bvh;
use crate::{Containment, CullCounters, CullOptions, Frustum, PlaneMask, Visible, ALL_PLANES};

/// Per-node plane-coherency state for [`Bvh::cull_coherent`]: the plane that last rejected
/// each node, tested first next frame.
#[derive(Debug, Clone, Default)]
pub struct CoherencyCache {
    start: Vec<u8>,
}

impl CoherencyCache {
    /// An empty cache (sized on first use).
    pub fn new() -> Self {
        Self::default()
    }
}

/// [`Bvh::count_in_frustum`] in steps: a count that stops when asked and goes on where it
/// stopped, so that a thread with nothing else to do (while another walks a tree serially)
/// can make it in pieces, and whoever needs the number finishes it.
#[derive(Debug, Clone)]
pub struct FrustumCount {
    frustum: Frustum,
    stack: Vec<(u32, PlaneMask)>,
    count: u64,
}

/// Nodes a [`FrustumCount`] visits between asking whether to stop.
const COUNT_STEP: u32 = 64;

impl FrustumCount {
    /// A count of `bvh`'s items in `frustum`, not started.
    pub fn new(bvh: &Bvh, frustum: &Frustum) -> Self {
        let stack = if bvh.nodes.is_empty() { Vec::new() } else { vec![(0, ALL_PLANES)] };
        Self { frustum: *frustum, stack, count: bvh.unbounded.len() as u64 }
    }

    /// Counts on over `bvh` (the tree the count was made for) until it is done or `stop()`,
    /// asked first and then every 64 nodes, says to stop. True when done.
    pub fn run(&mut self, bvh: &Bvh, mut stop: impl FnMut() -> bool) -> bool {
        let frustum = &self.frustum;
        let mut tests = 0u32;
        let mut visited = 0u32;
        loop {
            if visited.is_multiple_of(COUNT_STEP) && !self.stack.is_empty() && stop() {
                return false;
            }
            visited = visited.wrapping_add(1);
            let Some((i, mut mask)) = self.stack.pop() else { return true };
            let n = &bvh.nodes[i as usize];
            if mask != 0 && frustum.classify_counted(&n.aabb(), &mut mask, &mut 0, &mut tests) == Containment::Outside {
                continue;
            }
            if mask == 0 {
                self.count += bvh.subtree_items(i).len() as u64;
            } else if n.is_leaf() {
                if n.count == 1 {
                    self.count += 1;
                } else {
                    for s in n.index..n.index + n.count {
                        let mut m = mask;
                        let b = &bvh.item_boxes[s as usize];
                        self.count +=
                            (frustum.classify_counted(b, &mut m, &mut 0, &mut tests) != Containment::Outside) as u64;
                    }
                }
            } else {
                self.stack.push((n.index + 1, mask));
                self.stack.push((n.index, mask));
            }
        }
    }

    /// True when the count is finished.
    pub fn is_done(&self) -> bool {
        self.stack.is_empty()
    }

    /// The items counted so far: all of them once [`FrustumCount::is_done`].
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Counts what is left over `bvh` without stopping; the whole count.
    pub fn finish(mut self, bvh: &Bvh) -> u64 {
        self.run(bvh, || false);
        self.count
    }
}

impl Bvh {
    /// Frustum culling: appends every item whose box may intersect `frustum` to `out`
    /// (unbounded items first, never `inside`). Conservative.
    pub fn cull_with(&self, frustum: &Frustum, opts: CullOptions, out: &mut Vec<Visible>) -> CullCounters {
        self.cull_impl(frustum, opts.plane_masking, None, out)
    }

    /// How many items [`Bvh::cull_with`] with plane masking would return, without listing
    /// them: a node found wholly inside the frustum adds its subtree's item count at once
    /// (the depth-first layout keeps a subtree's items contiguous, so the count is the span
    /// from its leftmost to its rightmost leaf), so the cost grows with the nodes the frustum
    /// boundary cuts, not with the items inside.
    pub fn count_in_frustum(&self, frustum: &Frustum) -> u64 {
        FrustumCount::new(self, frustum).finish(self)
    }

    /// The slots in `items` of node `i`'s subtree: from its leftmost leaf's first to its
    /// rightmost leaf's last (contiguous in the depth-first layout).
    fn subtree_items(&self, i: u32) -> std::ops::Range<u32> {
        let (mut first, mut last) = (&self.nodes[i as usize], &self.nodes[i as usize]);
        while !first.is_leaf() {
            first = &self.nodes[first.index as usize];
        }
        while !last.is_leaf() {
            last = &self.nodes[last.index as usize + 1];
        }
        first.index..last.index + last.count
    }

    /// Frustum culling with plane masking and plane coherency: each node first tests the
    /// plane that rejected it last time (kept in `cache`).
    pub fn cull_coherent(&self, frustum: &Frustum, cache: &mut CoherencyCache, out: &mut Vec<Visible>) -> CullCounters {
        if cache.start.len() != self.nodes.len() {
            cache.start.clear();
            cache.start.resize(self.nodes.len(), 0);
        }
        self.cull_impl(frustum, true, Some(&mut cache.start), out)
    }

    fn cull_impl(
        &self,
        frustum: &Frustum,
        masking: bool,
        mut coherency: Option<&mut Vec<u8>>,
        out: &mut Vec<Visible>,
    ) -> CullCounters {
        let mut stats = CullCounters::default();
        let before = out.len();
        out.extend(self.unbounded.iter().map(|&index| Visible { index, inside: false }));
        if self.nodes.is_empty() {
            stats.visible = (out.len() - before) as u64;
            return stats;
        }
        let mut tests = 0u32;
        let mut stack: Vec<(u32, PlaneMask)> = Vec::with_capacity(64);
        stack.push((0, ALL_PLANES));
        while let Some((i, parent_mask)) = stack.pop() {
            let n = &self.nodes[i as usize];
            // Without masking every node tests all six planes again.
            let mut mask = if masking { parent_mask } else { ALL_PLANES };
            if mask != 0 {
                stats.boxes_tested += 1;
                let mut tmp = 0u8;
                let start = match coherency.as_deref_mut() {
                    Some(s) => &mut s[i as usize],
                    None => &mut tmp,
                };
                let c = frustum.classify_counted(&n.aabb(), &mut mask, start, &mut tests);
                if c == Containment::Outside {
                    continue;
                }
            }
            if n.is_leaf() {
                let r = n.index..n.index + n.count;
                if n.count == 1 || mask == 0 {
                    out.extend(r.map(|s| Visible { index: self.items[s as usize], inside: mask == 0 }));
                } else {
                    for s in r {
                        let mut m = if masking { mask } else { ALL_PLANES };
                        let mut st = 0u8;
                        stats.boxes_tested += 1;
                        let b = &self.item_boxes[s as usize];
                        if frustum.classify_counted(b, &mut m, &mut st, &mut tests) != Containment::Outside {
                            out.push(Visible { index: self.items[s as usize], inside: m == 0 });
                        }
                    }
                }
            } else {
                stack.push((n.index + 1, mask));
                stack.push((n.index, mask));
            }
        }
        stats.plane_tests = tests as u64;
        stats.visible = (out.len() - before) as u64;
        stats
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::BvhPreset;
    use crate::Visit;
    use glam::Vec3;
    use sightline_scene::Aabb;
    use sightline_scene::{Angle, Camera, LookAt};

    pub(crate) fn grid_boxes() -> Vec<Aabb> {
        let mut v = Vec::new();
        for x in 0..20 {
            for z in 0..20 {
                let p = Vec3::new(x as f32 * 3.0 - 30.0, 0.0, z as f32 * 3.0 - 30.0);
                v.push(Aabb::new(p, p + Vec3::ONE));
            }
        }
        v
    }

    #[test]
    fn cull_variants_agree_with_brute_force() {
        let boxes = grid_boxes();
        let bvh = Bvh::build(&boxes, BvhPreset::Fast, 4);
        let cam = Camera::perspective(
            &LookAt {
                eye: Vec3::new(0.0, 5.0, 0.0),
                target: Vec3::new(10.0, 0.0, 10.0),
                up: Vec3::Y,
                fovy: Angle::degrees(50.0),
                near: 0.1,
                far: 30.0,
            },
            1.5,
        )
        .unwrap();
        let f = Frustum::from_camera(&cam);
        let brute: Vec<u32> =
            (0..boxes.len() as u32).filter(|&i| f.classify(&boxes[i as usize]) != Containment::Outside).collect();
        assert!(!brute.is_empty() && brute.len() < boxes.len());
        let mut cache = CoherencyCache::new();
        for variant in 0..4 {
            let mut out = Vec::new();
            match variant {
                0 => bvh.cull_with(&f, CullOptions { plane_masking: true }, &mut out),
                1 => bvh.cull_with(&f, CullOptions { plane_masking: false }, &mut out),
                _ => bvh.cull_coherent(&f, &mut cache, &mut out),
            };
            let mut got: Vec<u32> = out.iter().map(|v| v.index).collect();
            got.sort_unstable();
            // Every item the brute force keeps is kept (the tree may keep a few more only if
            // its node test is looser, which plane tests on item boxes exclude).
            assert_eq!(got, brute, "variant {variant}");
            for v in &out {
                if v.inside {
                    assert_eq!(f.classify(&boxes[v.index as usize]), Containment::Inside);
                }
            }
        }
        let mut got = Vec::new();
        bvh.traverse_front_to_back(
            Some(&f),
            cam.view.eye,
            |_| Visit::Continue,
            |v| {
                got.push(v.index);
                Visit::Continue
            },
        );
        got.sort_unstable();
        assert_eq!(got, brute);
    }

    /// 3,000 random boxes over a 120 × 10 × 120 block, sides 0.1 to 4.
    pub(crate) fn random_boxes(rng: &mut sightline_scene::rng::Rng) -> Vec<Aabb> {
        (0..3000)
            .map(|_| {
                let p = Vec3::new(rng.range(-60.0, 60.0), rng.range(-5.0, 5.0), rng.range(-60.0, 60.0));
                Aabb::new(p, p + Vec3::new(rng.range(0.1, 4.0), rng.range(0.1, 4.0), rng.range(0.1, 4.0)))
            })
            .collect()
    }

    #[test]
    fn counting_in_the_frustum_equals_listing() {
        // Random boxes (a few NaN, empty or unbounded) under random cameras, leaves of one
        // and of several items: the count is the length of the list, cameras that see all,
        // some or none of the boxes alike.
        let mut rng = sightline_scene::rng::Rng::new(17);
        let mut boxes = random_boxes(&mut rng);
        boxes[7] = Aabb::EMPTY;
        boxes[11] = Aabb::new(Vec3::splat(f32::NEG_INFINITY), Vec3::splat(f32::INFINITY));
        for leaf in [1, 4, 8] {
            let bvh = Bvh::build(&boxes, BvhPreset::Fast, leaf);
            for k in 0..60 {
                let eye = Vec3::new(rng.range(-90.0, 90.0), rng.range(-10.0, 30.0), rng.range(-90.0, 90.0));
                let target = Vec3::new(rng.range(-30.0, 30.0), 0.0, rng.range(-30.0, 30.0));
                let look = LookAt {
                    eye,
                    target,
                    up: Vec3::Y,
                    fovy: Angle::degrees(rng.range(10.0, 120.0)),
                    near: 0.1,
                    far: [5.0, 40.0, 400.0][k % 3],
                };
                let f = Frustum::from_camera(&Camera::perspective(&look, 1.5).unwrap());
                let mut out = Vec::new();
                bvh.cull_with(&f, CullOptions::default(), &mut out);
                assert_eq!(bvh.count_in_frustum(&f), out.len() as u64, "leaf {leaf}, camera {k}");
                // In pieces: stopped after every step (or at once, every third step), then
                // finished; the same count.
                let mut pieces = FrustumCount::new(&bvh, &f);
                let mut steps = 0;
                while !pieces.run(&bvh, || {
                    steps += 1;
                    steps % 2 == 0 || steps % 3 == 0
                }) {
                    assert!(!pieces.is_done());
                }
                assert!(pieces.is_done());
                assert_eq!(pieces.count(), out.len() as u64, "leaf {leaf}, camera {k}, {steps} steps");
            }
        }
    }
}

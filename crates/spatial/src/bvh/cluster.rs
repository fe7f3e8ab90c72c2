//! Clusters: a mesh split into spatially coherent groups of [`CLUSTER_MIN`]–[`CLUSTER_MAX`]
//! triangles, each with its own box, so that one huge mesh (a 10^6-triangle scan, a city
//! exported as one OBJ) is culled in parts rather than all or nothing — the idea behind
//! meshlet / cluster culling (e.g. Karis et al., "Nanite", SIGGRAPH 2021 course; Wihlidal,
//! "Optimizing the Graphics Pipeline with Compute", GDC 2016).
//!
//! Construction: a top-down split (as in a kd-tree build), recursively (in parallel with
//! rayon) until a part has at most `CLUSTER_MAX` triangles: each part is cut across the
//! longest axis of its triangles' box centers, at an empty stretch that no triangle box
//! crosses when one leaves a quarter to three quarters of them on each side, else at the
//! median. So clusters hold at most 128 triangles, most of them 64 or more, and are compact
//! cells. The facing groups (below) are made by a counting sort and split side by side; the
//! split's cost is its per-item histogram of `gap_split`, once per level. A PLOC BVH's
//! subtrees were tried first and rejected: on regular grids (subdivided faces, scanned
//! surfaces) PLOC merges into long strips, since the SAH cannot tell a strip from a square on
//! flat geometry, and strips spanning a whole facade cull badly. A cluster is a range of the
//! stored triangle permutation, so drawing it needs only the original triangle indices, and
//! a renderer can still write the ORIGINAL triangle IDs.

use sightline_scene::{Aabb, Mesh};

use glam::Vec3;
use rayon::prelude::*;

use super::triangles::triangle_boxes;
use crate::{AabbExt, BoxKind};

/// Cluster size aimed for at least (cuts at empty stretches, and small groups of one
/// facing, can give smaller clusters).
pub const CLUSTER_MIN: usize = 64;
/// Largest cluster size.
pub const CLUSTER_MAX: usize = 128;

/// Per-item passes over fewer items than this are not split across threads.
const PARALLEL_MIN: usize = 1 << 14;

/// One cluster: a box (mesh-local) and a range of the cluster-ordered permutation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cluster {
    /// Bounds of the cluster's triangles, mesh-local.
    pub aabb: Aabb,
    /// First slot in [`MeshClusters::permutation`].
    pub first: u32,
    /// Number of triangles.
    pub count: u32,
}

/// A mesh's clusters and the triangle permutation they index.
#[derive(Debug, Clone, Default)]
pub struct MeshClusters {
    clusters: Vec<Cluster>,
    permutation: Vec<u32>,
}

impl MeshClusters {
    /// Clusters `mesh`'s triangles (one cluster when it has at most [`CLUSTER_MAX`]).
    ///
    /// Meshes with more than [`CLUSTER_MAX`] triangles are first grouped by facing (the sign
    /// and axis of each triangle's dominant normal component), then split spatially within each
    /// group: clusters of one facing have narrow normal cones, so a renderer can drop a whole
    /// cluster that faces away (cluster back-face culling) — a facade cluster is then exactly
    /// planar, not folded around a corner.
    pub fn build(mesh: &Mesh) -> MeshClusters {
        let boxes = triangle_boxes(mesh.positions(), mesh.indices());
        if mesh.triangle_count() <= CLUSTER_MAX {
            return Self::from_triangle_boxes(&boxes);
        }
        let groups: Vec<u8> = (0..mesh.triangle_count())
            .into_par_iter()
            .with_min_len(PARALLEL_MIN)
            .map(|t| facing(mesh.triangle_positions(t)))
            .collect();
        Self::from_grouped_boxes(&boxes, &groups)
    }

    /// Clusters items given by their boxes (item `i` is `boxes[i]`); empty boxes are left
    /// out, NaN/infinite ones form clusters of their own with an unbounded (NaN) box.
    pub fn from_triangle_boxes(boxes: &[Aabb]) -> MeshClusters {
        Self::from_grouped_boxes(boxes, &vec![0; boxes.len()])
    }

    /// Like [`MeshClusters::from_triangle_boxes`], but no cluster mixes items of different
    /// `groups[i]`.
    pub fn from_grouped_boxes(boxes: &[Aabb], groups: &[u8]) -> MeshClusters {
        let group = |i: usize| groups.get(i).copied().unwrap_or(0) as usize;
        // Group first, by a counting sort (stable: ties keep index order), leaving out empty
        // boxes and setting aside unbounded ones.
        let mut starts = [0usize; 257];
        let mut unbounded: Vec<u32> = Vec::new();
        for (i, b) in boxes.iter().enumerate() {
            match b.kind() {
                BoxKind::Finite => starts[group(i) + 1] += 1,
                BoxKind::Unbounded => unbounded.push(i as u32),
                BoxKind::Empty => {}
            }
        }
        for g in 0..256 {
            starts[g + 1] += starts[g];
        }
        let mut permutation = vec![0u32; starts[256]];
        let mut next = starts;
        for (i, b) in boxes.iter().enumerate() {
            if b.kind() == BoxKind::Finite {
                permutation[next[group(i)]] = i as u32;
                next[group(i)] += 1;
            }
        }
        let centers: Vec<Vec3> = boxes.par_iter().with_min_len(PARALLEL_MIN).map(|b| b.center()).collect();
        // Then split each group's range, the groups side by side.
        let mut parts: Vec<(u32, &mut [u32])> = Vec::new();
        let mut rest = permutation.as_mut_slice();
        for g in starts.windows(2).filter(|g| g[1] > g[0]) {
            let (part, tail) = std::mem::take(&mut rest).split_at_mut(g[1] - g[0]);
            parts.push((g[0] as u32, part));
            rest = tail;
        }
        let ranges: Vec<(u32, u32)> =
            parts.into_par_iter().flat_map_iter(|(base, part)| median_split(boxes, &centers, part, base)).collect();
        let mut clusters: Vec<Cluster> = ranges
            .into_par_iter()
            .with_min_len(PARALLEL_MIN / CLUSTER_MAX)
            .map(|(first, count)| Cluster {
                aabb: permutation[first as usize..(first + count) as usize]
                    .iter()
                    .fold(Aabb::EMPTY, |a, &t| a.union(&boxes[t as usize])),
                first,
                count,
            })
            .collect();
        for chunk in unbounded.chunks(CLUSTER_MAX) {
            clusters.push(Cluster {
                aabb: Aabb::new(Vec3::NAN, Vec3::NAN),
                first: permutation.len() as u32,
                count: chunk.len() as u32,
            });
            permutation.extend_from_slice(chunk);
        }
        MeshClusters { clusters, permutation }
    }

    /// The clusters.
    pub fn clusters(&self) -> &[Cluster] {
        &self.clusters
    }

    /// The original triangle indices of cluster `c`.
    pub fn triangles(&self, c: usize) -> &[u32] {
        let cl = &self.clusters[c];
        &self.permutation[cl.first as usize..(cl.first + cl.count) as usize]
    }

    /// Original triangle indices in cluster order (clusters are ranges of this).
    pub fn permutation(&self) -> &[u32] {
        &self.permutation
    }

    /// Heap bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.clusters.capacity() * std::mem::size_of::<Cluster>() + self.permutation.capacity() * 4
    }
}

/// Facing group of a triangle: 2·axis + (component < 0) of its normal's largest component,
/// 6 for degenerate triangles.
fn facing([a, b, c]: [Vec3; 3]) -> u8 {
    let n = (b - a).cross(c - a);
    let m = n.abs();
    if !(m.max_element() > 0.0) {
        return 6;
    }
    let axis = if m.x >= m.y && m.x >= m.z {
        0
    } else if m.y >= m.z {
        1
    } else {
        2
    };
    2 * axis + (n[axis as usize] < 0.0) as u8
}

/// Looks for an empty stretch of the axis — a street between two buildings, the space
/// between two parts of a model — that no item's box crosses (32 bins over the centers'
/// range), leaving between a quarter and three quarters of the items on each side; splits
/// there, so that no cluster straddles empty space. Returns the left count after
/// partitioning `perm`, or `None` when there is no such gap.
fn gap_split(boxes: &[Aabb], perm: &mut [u32], axis: usize, a0: f32, a1: f32) -> Option<usize> {
    const BINS: usize = 32;
    let n = perm.len();
    let extent = a1 - a0;
    if !(extent > 0.0) || !extent.is_finite() {
        return None;
    }
    // Through i32: the value is clamped into range, and a conversion to usize costs extra
    // instructions for values past i64 (none here). Per item and level, this is the cost.
    let bin_of = |v: f32| ((v - a0) / extent * BINS as f32).clamp(0.0, (BINS - 1) as f32) as i32 as usize;
    let center = |t: u32| bin_of(boxes[t as usize].center()[axis]);
    // How many boxes cross each bin (difference array), and how many centers fall in it.
    let mut cross = [0i64; BINS + 1];
    let mut counts = [0usize; BINS];
    for &t in perm.iter() {
        let b = &boxes[t as usize];
        cross[bin_of(b.min[axis])] += 1;
        cross[bin_of(b.max[axis]) + 1] -= 1;
        counts[center(t)] += 1;
    }
    let mut best: Option<(usize, usize)> = None; // (empty bin, items left of it)
    let (mut covered, mut left) = (0i64, 0usize);
    for k in 0..BINS {
        covered += cross[k];
        if covered == 0
            && left >= n / 4
            && left <= 3 * n / 4
            && best.is_none_or(|(_, l)| left.abs_diff(n / 2) < l.abs_diff(n / 2))
        {
            best = Some((k, left));
        }
        left += counts[k];
    }
    let (k, count) = best?;
    let mut i = 0;
    for j in 0..n {
        if center(perm[j]) < k {
            perm.swap(i, j);
            i += 1;
        }
    }
    debug_assert_eq!(i, count);
    Some(i)
}

/// Splits `perm` (item ids, whose centers are `centers[id]`) across the longest axis, at an
/// empty stretch ([`gap_split`]) or else the median, until parts have at most `CLUSTER_MAX`
/// items; returns `(first, count)` ranges (offset by `base`) in order. Each cut leaves at
/// most three quarters on a side, so the recursion is at most log_{4/3}(n / CLUSTER_MAX)
/// deep.
fn median_split(boxes: &[Aabb], centers: &[Vec3], perm: &mut [u32], base: u32) -> Vec<(u32, u32)> {
    let n = perm.len();
    if n == 0 {
        return Vec::new();
    }
    if n <= CLUSTER_MAX {
        return vec![(base, n as u32)];
    }
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for &t in perm.iter() {
        lo = lo.min(centers[t as usize]);
        hi = hi.max(centers[t as usize]);
    }
    let axis = Aabb::new(lo, hi).longest_axis();
    let mid = match gap_split(boxes, perm, axis, lo[axis], hi[axis]) {
        Some(mid) => mid,
        None => {
            let mid = n / 2;
            perm.select_nth_unstable_by(mid, |&a, &b| {
                centers[a as usize][axis].total_cmp(&centers[b as usize][axis]).then(a.cmp(&b))
            });
            mid
        }
    };
    let (left, right) = perm.split_at_mut(mid);
    let (mut l, r) = if n > PARALLEL_MIN {
        rayon::join(
            || median_split(boxes, centers, left, base),
            || median_split(boxes, centers, right, base + mid as u32),
        )
    } else {
        (median_split(boxes, centers, left, base), median_split(boxes, centers, right, base + mid as u32))
    };
    l.extend(r);
    l
}

#[cfg(test)]
mod tests {
    use super::*;
    use sightline_scene::shapes;

    #[test]
    fn clusters_partition_the_mesh_and_bound_their_triangles() {
        let mesh = shapes::subdivided_box("b", Vec3::ZERO, Vec3::new(10.0, 4.0, 6.0), [40, 16, 24], true).unwrap();
        let n = mesh.triangle_count();
        let mc = MeshClusters::build(&mesh);
        let mut seen = vec![false; n];
        let mut small = 0;
        for (c, cl) in mc.clusters().iter().enumerate() {
            assert!(cl.count as usize <= CLUSTER_MAX);
            small += ((cl.count as usize) < CLUSTER_MIN) as usize;
            for &t in mc.triangles(c) {
                assert!(!std::mem::replace(&mut seen[t as usize], true));
                let [a, b, cc] = mesh.triangle_positions(t as usize);
                assert!(cl.aabb.contains(&Aabb::of_triangle(a, b, cc)));
            }
        }
        assert!(seen.iter().all(|&s| s));
        // Most clusters are in the target range; coherent: boxes much smaller than the mesh.
        assert!(small * 10 <= mc.clusters().len(), "{small} of {}", mc.clusters().len());
        // Coherent: the clusters' boxes are hardly bigger than the surface they hold (a flat
        // cluster's box has half-area = its area; a random split would span the whole mesh).
        let boxes: f32 = mc.clusters().iter().map(|c| c.aabb.half_area()).sum();
        let surface = 2.0 * mesh.aabb().half_area();
        assert!(boxes < 2.0 * surface, "{boxes} vs {surface}");
    }

    #[test]
    fn small_and_empty_meshes() {
        let cube = shapes::cube("c").unwrap();
        let mc = MeshClusters::build(&cube);
        assert_eq!(mc.clusters().len(), 1);
        assert_eq!(mc.triangles(0).len(), 12);
        let e = Mesh::new("e", vec![], None, None, vec![]).unwrap();
        assert!(MeshClusters::build(&e).clusters().is_empty());
    }

    /// Grouping by a counting sort and splitting the groups side by side (in parallel, over
    /// enough items for every parallel path) give the clusters of the plain way: a stable
    /// sort by group, then each group's range split in turn. Empty boxes are left out and
    /// unbounded ones kept apart, wherever they fall.
    #[test]
    fn grouped_clusters_are_those_of_a_stable_sort_and_groups_split_in_turn() {
        let mut rng = sightline_scene::rng::Rng::new(17);
        let n = 3 * PARALLEL_MIN;
        let mut boxes: Vec<Aabb> = (0..n)
            .map(|i| {
                // Two blobs with a street between them, and a scatter: gaps and medians both.
                let x = if i % 3 == 0 { rng.range(0.0, 40.0) } else { rng.range(60.0, 100.0) };
                let p = Vec3::new(x, rng.range(0.0, 5.0), rng.range(0.0, 30.0));
                Aabb::new(p, p + Vec3::splat(rng.range(0.0, 0.5)))
            })
            .collect();
        for k in (0..n).step_by(997) {
            boxes[k] = if k % 2 == 0 { Aabb::EMPTY } else { Aabb::new(Vec3::NAN, Vec3::ONE) };
        }
        let groups: Vec<u8> = (0..n).map(|i| [0, 3, 3, 7, 255][i * 7 % 5]).collect();
        let got = MeshClusters::from_grouped_boxes(&boxes, &groups);

        let centers: Vec<Vec3> = boxes.iter().map(|b| b.center()).collect();
        let mut perm: Vec<u32> = (0..n as u32).filter(|&i| boxes[i as usize].kind() == BoxKind::Finite).collect();
        perm.sort_by_key(|&i| groups[i as usize]);
        let mut ranges = Vec::new();
        let mut start = 0;
        while start < perm.len() {
            let len = perm[start..].iter().take_while(|&&t| groups[t as usize] == groups[perm[start] as usize]).count();
            ranges.extend(median_split(&boxes, &centers, &mut perm[start..start + len], start as u32));
            start += len;
        }
        let finite = perm.len();
        assert_eq!(&got.permutation()[..finite], &perm[..]);
        let unbounded: Vec<u32> = (0..n as u32).filter(|&i| boxes[i as usize].kind() == BoxKind::Unbounded).collect();
        assert_eq!(&got.permutation()[finite..], &unbounded[..]);
        assert_eq!(got.clusters().len(), ranges.len() + unbounded.len().div_ceil(CLUSTER_MAX));
        for (c, &(first, count)) in got.clusters().iter().zip(&ranges) {
            let aabb = perm[first as usize..(first + count) as usize]
                .iter()
                .fold(Aabb::EMPTY, |a, &t| a.union(&boxes[t as usize]));
            assert_eq!((c.first, c.count, c.aabb), (first, count, aabb));
        }
    }
}

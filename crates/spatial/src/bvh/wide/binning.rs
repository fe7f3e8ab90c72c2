//! Splitting a set of primitives in two by the surface area heuristic evaluated on binned
//! centroids, as Embree builds its triangle BVHs (Wald 2007, "On fast Construction of
//! SAH-based Bounding Volume Hierarchies"; Wald et al. 2014, "Embree: A Kernel Framework
//! for Efficient CPU Ray Tracing"); [`super::sah`] builds the wide tree from such splits.
//!
//! One pass drops every primitive into its bin on each of the three axes ([`BINS`] bins of
//! box centroids at most, growing the bin's box and count), a sweep from each end gives
//! the area and count on either side of every bin boundary, and the boundary with the
//! smallest `area(left)·count(left) + area(right)·count(right)` wins. The primitives are
//! then partitioned in place, so that each side is a run of the primitive array. Under one
//! primitive per leaf (a BLAS of quads) most splits are of two primitives; those skip the
//! bins and split the way the bins would.
//!
//! Bounded work on any input: when the bins cannot separate a set (all centroids in one
//! bin, e.g. coincident triangles) or a path grows deeper than [`MAX_SAH_DEPTH`] binary
//! splits, the set is cut in the middle of its range instead (Embree's fallback). Every
//! split leaves both sides non-empty and middle cuts halve, so a tree built from these
//! splits is at most `MAX_SAH_DEPTH + log2(n)` binary levels deep.
//!
//! Deterministic for any thread count: bins are merged with exact operations (min, max,
//! integer counts) and partitions run serially.

use glam::Vec4;
use rayon::prelude::*;

/// Most centroid bins per axis (Embree's count for object splits); smaller sets use
/// fewer, `4 + n / 20` as Embree does, since sweeping empty bins costs more than it finds.
const BINS: usize = 32;

/// Binary splits along one path beyond which sets are cut in the middle.
pub(super) const MAX_SAH_DEPTH: u32 = 48;

/// Sets at least this large are binned in parallel chunks.
const PARALLEL_BINNING: usize = 1 << 15;

/// Chunk size of parallel binning.
pub(super) const BIN_CHUNK: usize = 1 << 13;

/// A primitive's box (the `w` lanes are zero).
pub(super) type Prim = Bounds;

/// A box accumulated by min and max; starts inverted.
#[derive(Clone, Copy)]
pub(super) struct Bounds {
    pub(super) lo: Vec4,
    pub(super) hi: Vec4,
}

impl Bounds {
    pub(super) const EMPTY: Bounds = Bounds { lo: Vec4::splat(f32::INFINITY), hi: Vec4::splat(f32::NEG_INFINITY) };

    #[inline(always)]
    fn grow(&mut self, lo: Vec4, hi: Vec4) {
        self.lo = self.lo.min(lo);
        self.hi = self.hi.max(hi);
    }

    #[inline(always)]
    pub(super) fn union(&self, o: &Bounds) -> Bounds {
        Bounds { lo: self.lo.min(o.lo), hi: self.hi.max(o.hi) }
    }

    /// Twice the centre (the bins are scaled to match, saving a multiply).
    #[inline(always)]
    fn centroid2(&self) -> Vec4 {
        self.lo + self.hi
    }

    /// The box of `prims` and the box of their doubled centroids.
    pub(super) fn of(prims: &[Prim]) -> (Bounds, Bounds) {
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
    pub(super) fn half_area(&self) -> f32 {
        let d = self.hi - self.lo;
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// A contiguous range of the primitive array with its box and its centroids' box.
#[derive(Clone, Copy)]
pub(super) struct Set {
    pub(super) start: usize,
    pub(super) end: usize,
    pub(super) bounds: Bounds,
    /// Box of the doubled centroids.
    pub(super) centroids: Bounds,
    /// Binary splits made above this set.
    pub(super) depth: u32,
}

impl Set {
    pub(super) fn len(&self) -> usize {
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

    /// `self.bin(c, axis) < boundary` for a boundary in `1 .. count`, without the clamps
    /// and the conversion: a position `x` (as `bin` computes it) lands below bin `boundary`
    /// exactly when `x < boundary` (the clamps keep `x` under `boundary` or at least it),
    /// or when `x` is not a number (bin 0).
    #[inline(always)]
    fn left_of(&self, c: Vec4, axis: usize, boundary: usize) -> bool {
        !((c[axis] - self.origin[axis]) * self.scale[axis] >= boundary as f32)
    }
}

/// Boxes and counts of the bins on each axis.
pub(super) struct Bins {
    boxes: [[Bounds; BINS]; 3],
    counts: [[u32; BINS]; 3],
}

impl Bins {
    pub(super) fn new() -> Bins {
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

/// Splits `set` (a range of `prims` and `ids`) in two non-empty sets: the binned SAH's
/// best boundary, or the middle of the range when the bins cannot separate it or the path
/// is already `MAX_SAH_DEPTH` splits deep. With a `leaf_cost` (the set fits in a leaf),
/// `None` instead when no boundary costs less.
pub(super) fn split(
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
        0 => partition(prims, ids, run, |p| map.left_of(p.centroid2(), 0, boundary)),
        1 => partition(prims, ids, run, |p| map.left_of(p.centroid2(), 1, boundary)),
        _ => partition(prims, ids, run, |p| map.left_of(p.centroid2(), 2, boundary)),
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

    /// [`Mapping::left_of`] answers as the bin numbers do, on centroids inside, at the ends
    /// of and outside the mapped range, infinite and not a number, for every boundary of
    /// mappings of every bin count (and of axes without extent).
    #[test]
    fn left_of_agrees_with_the_bin_numbers() {
        let mut tested = 0;
        for prims in [2usize, 30, 100, 600, 10_000] {
            for (lo, hi) in [(0.0f32, 1.0f32), (-3.0, 7.5), (1e-3, 1e-3 + 1e-6), (-3e38, 3e38), (2.0, 2.0)] {
                let c = Bounds { lo: Vec4::splat(lo), hi: Vec4::new(hi, lo, hi, 0.0) };
                let map = Mapping::new(&c, prims);
                let mut xs: Vec<f32> = vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, -f32::MAX, lo, hi];
                xs.extend((0..=4000).map(|k| lo + (hi - lo) * (k as f32 / 4000.0)));
                // Where positions come out at a bin boundary exactly, or nearly.
                xs.extend((0..=map.count).map(|k| map.origin.x + k as f32 / map.scale.x).filter(|x| x.is_finite()));
                xs.extend(xs.clone().iter().flat_map(|&x| [x.next_up(), x.next_down()]));
                for &x in &xs {
                    let v = Vec4::splat(x);
                    for axis in 0..3 {
                        for boundary in 1..map.count {
                            assert_eq!(
                                map.left_of(v, axis, boundary),
                                map.bin(v, axis) < boundary,
                                "x {x}, axis {axis}, boundary {boundary}, {prims} prims, range {lo}..{hi}"
                            );
                            tested += 1;
                        }
                    }
                }
            }
        }
        assert!(tested > 1_000_000, "{tested}");
    }

    /// [`split_two`] gives, bit for bit, what the bins give, on pairs of boxes drawn from
    /// a few coordinates (so that centroids often tie on some axes, or on all, or overflow)
    /// and sizes (flat, and too large for a finite area); and [`split`] gives what the bins
    /// give a pair at [`MAX_SAH_DEPTH`] (the middle cut).
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
            // As deep as the SAH goes, `split` must leave the pair to the bins' middle cut.
            let deep = Set { start: 0, end: 2, bounds, centroids, depth: MAX_SAH_DEPTH };
            let (mut dp, mut di) = (prims.to_vec(), vec![0u32, 1]);
            let (dl, dr) = split(&mut dp, &mut di, &deep, None, &mut Bins::new()).unwrap();
            let (mut mp, mut mi) = (prims.to_vec(), vec![0u32, 1]);
            let (ml, mr) = split_binned(&mut mp, &mut mi, &deep, None, &mut Bins::new()).unwrap();
            assert_eq!((key(&dl), key(&dr), &di), (key(&ml), key(&mr), &mi));
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
}

//! Packet traversal of a 4-wide BVH: masked, ordered, with early hit and frustum culling.
//!
//! The scheme is the BVH packet traversal of Wald, Boulos & Shirley 2007 ("Ray Tracing
//! Deformable Scenes Using Dynamic Bounding Volume Hierarchies") with the active-ray mask of
//! Overbeck, Ramamoorthi & Mark 2008 ("Large Ray Packets for Real-time Whitted Ray
//! Tracing"), on a 4-wide tree. A node is entered with the mask of lanes that may hit it;
//! for its children:
//!
//! 1. *early hit*: one lead lane is tested against all four boxes at once; an inner child it
//!    hits is entered with the whole mask (the common case for coherent rays). The lead is
//!    a lane at the packet's center when one is active, else the first active lane: the
//!    central ray stands for the packet better than a corner's (aerial path of the exported
//!    city, one caster casting each camera twice, the two leads taking turns going first:
//!    24.37 and 26.00 ms against 24.44 and 26.34 ms with the first active lane, within
//!    noise but ahead; the street path as fast);
//! 2. *frustum cull*: the other children are tested against the packet's four beam planes,
//!    all sixteen plane–box pairs at once (`Isa::culls4`); a box outside one plane is hit
//!    by no lane;
//! 3. the rest, and every leaf, get an exact mask: every active lane tested in SIMD, chunk
//!    by chunk against all of those boxes, so that a chunk's rays are loaded once per node
//!    (box by box, loading them again for each, the aerial and street frames took about 2%
//!    longer).
//!
//! Entering a node starts the loads of all its children (their nodes, and through `soon`
//! their leaves' primitives) before the box tests decide which are reached: for a packet most
//! are, and the tests then hide the cache misses (an aerial city view, one thread: −8 %).
//!
//! Lane tests clip against each lane's current closest hit, so subtrees behind what the
//! packet already sees drop out (occlusion). Children are visited near to far along the
//! lead lane. Box tests use the robust slab test of Ize 2013 ("Robust BVH Ray
//! Traversal"): the exit distance is scaled up by 1 + 2⁻²⁰ (more than Ize's 1 + 2γ₃ and than
//! the triangle tie window), so rounding never loses a hit.

use glam::Vec4;
use sightline_spatial::bvh::wide::{WideBvh, WideNode, EMPTY_LINK, WIDTH};
use sightline_spatial::prefetch;

use super::isa::{Isa, Slab, ROBUST};
use super::packet::{chunk_bits, BeamPlanes, Hits, Rays, CHUNK, CHUNKS, TILE};

/// A pending subtree: (link, primitive count, lane mask).
pub(crate) type Entry = (u32, u32, u64);

/// Lanes of `mask` whose interval meets the box.
#[inline(always)]
pub(crate) fn box_mask<I: Isa>(rays: &Rays, hits: &Hits, lo: &[f32; 3], hi: &[f32; 3], mask: u64) -> u64 {
    let chunk = |c: usize| Slab {
        o: [&rays.o[0][c], &rays.o[1][c], &rays.o[2][c]],
        r: [&rays.r[0][c], &rays.r[1][c], &rays.r[2][c]],
        tmin: &hits.tmin[c],
        tmax: &hits.t[c],
    };
    let mut out = 0u64;
    // SAFETY (both kernels): `I` is only instantiated for an instruction set the CPU has
    // (`SimdLevel::resolve`).
    match rays.shared {
        // One origin for every lane (a perspective camera's rays): the box's corners relative
        // to it are found once for all chunks instead of once per lane.
        Some(o) => {
            let o = o.to_array();
            let dlo = [lo[0] - o[0], lo[1] - o[1], lo[2] - o[2]];
            let dhi = [hi[0] - o[0], hi[1] - o[1], hi[2] - o[2]];
            for c in 0..CHUNKS {
                let bits = chunk_bits(mask, c);
                if bits != 0 {
                    out |= (unsafe { I::slab16_shared(&chunk(c), &dlo, &dhi) } & bits) << (c * CHUNK);
                }
            }
        }
        None => {
            for c in 0..CHUNKS {
                let bits = chunk_bits(mask, c);
                if bits != 0 {
                    out |= (unsafe { I::slab16(&chunk(c), lo, hi) } & bits) << (c * CHUNK);
                }
            }
        }
    }
    out
}

/// The lanes of `mask` that meet each child box of `node` named in `which` (bit `k`: child
/// `k`), as [`box_mask`] finds them, but chunk by chunk: a chunk's reciprocals and interval
/// are loaded once for every box, and with one origin for every lane the boxes' corners
/// relative to it are found once for the node (four at a time).
#[inline(always)]
fn child_masks<I: Isa>(rays: &Rays, hits: &Hits, node: &WideNode, which: u32, mask: u64) -> [u64; WIDTH] {
    let corner = |v: &[[f32; WIDTH]; 3], k: usize| [v[0][k], v[1][k], v[2][k]];
    // SAFETY (both kernels): `I` is only instantiated for an instruction set the CPU has.
    match rays.shared {
        Some(o) => {
            let rel =
                |v: &[[f32; WIDTH]; 3]| [0, 1, 2].map(|a| (Vec4::from_array(v[a]) - Vec4::splat(o[a])).to_array());
            let (dlo, dhi) = (rel(&node.lo), rel(&node.hi));
            per_chunk(rays, hits, which, mask, |s, k| unsafe {
                I::slab16_shared(s, &corner(&dlo, k), &corner(&dhi, k))
            })
        }
        None => per_chunk(rays, hits, which, mask, |s, k| unsafe {
            I::slab16(s, &corner(&node.lo, k), &corner(&node.hi, k))
        }),
    }
}

/// `test(slab, k)` on every chunk of `mask` with lanes and every child `k` of `which`: each
/// child's lanes.
#[inline(always)]
fn per_chunk(rays: &Rays, hits: &Hits, which: u32, mask: u64, test: impl Fn(&Slab, usize) -> u64) -> [u64; WIDTH] {
    let mut out = [0u64; WIDTH];
    for c in 0..CHUNKS {
        let bits = chunk_bits(mask, c);
        if bits == 0 {
            continue;
        }
        let s = Slab {
            o: [&rays.o[0][c], &rays.o[1][c], &rays.o[2][c]],
            r: [&rays.r[0][c], &rays.r[1][c], &rays.r[2][c]],
            tmin: &hits.tmin[c],
            tmax: &hits.t[c],
        };
        let mut todo = which;
        while todo != 0 {
            let k = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            out[k] |= (test(&s, k) & bits) << (c * CHUNK);
        }
    }
    out
}

/// The four lanes at the center of a packet's [`TILE`] × [`TILE`] pixels (lane = row ·
/// TILE + column).
const CENTER: u64 = {
    let (a, b) = (TILE as u64 / 2 - 1, TILE as u64 / 2);
    1 << (a * TILE as u64 + a) | 1 << (a * TILE as u64 + b) | 1 << (b * TILE as u64 + a) | 1 << (b * TILE as u64 + b)
};

/// The lane of `mask` that leads a node's early-hit test and orders its children: a
/// [`CENTER`] lane when one is active, else the first active lane.
#[inline(always)]
fn lead_lane(mask: u64) -> usize {
    let center = mask & CENTER;
    (if center != 0 { center } else { mask }).trailing_zeros() as usize
}

/// Lane `i` against the four boxes of a node, four boxes per SIMD operation: the hit
/// children as a 4-bit mask, and per child a sort key (the entry distance for boxes the
/// lane hits, else the distance of the box center along the lane).
#[inline(always)]
fn lane_vs_node(rays: &Rays, hits: &Hits, i: usize, node: &WideNode) -> (u32, [f32; WIDTH]) {
    let (c, j) = (i / CHUNK, i % CHUNK);
    let mut near = Vec4::splat(hits.tmin[c][j]);
    let mut far = Vec4::splat(hits.t[c][j]);
    let mut along = Vec4::ZERO;
    for a in 0..3 {
        let (o, r, d) = (rays.o[a][c][j], rays.r[a][c][j], rays.d[a][c][j]);
        let (lo, hi) = (Vec4::from_array(node.lo[a]), Vec4::from_array(node.hi[a]));
        let t0 = (lo - Vec4::splat(o)) * r;
        let t1 = (hi - Vec4::splat(o)) * r;
        near = near.max(t0.min(t1));
        far = far.min(t0.max(t1));
        along += ((lo + hi) * 0.5 - Vec4::splat(o)) * d;
    }
    let hit = near.cmple(far * ROBUST);
    (hit.bitmask(), Vec4::select(hit, near, along).to_array())
}

/// Traverses `bvh` with the lanes of `mask`, calling `leaf(hits, first, count, lanes)` for
/// each leaf reached with the exact lanes that meet its box, and `soon(first, count)` for
/// each leaf child of a node as the node is entered (to start loading its primitives). `leaf` returns lanes it has
/// finished (any-hit queries), which then leave the traversal; the union is returned.
/// `stack` is scratch space, used above its current length and restored.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn traverse<I: Isa, F, S>(
    bvh: &WideBvh,
    rays: &Rays,
    hits: &mut Hits,
    fr: &BeamPlanes,
    mask: u64,
    stack: &mut Vec<Entry>,
    soon: S,
    mut leaf: F,
) -> u64
where
    F: FnMut(&mut Hits, u32, u32, u64) -> u64,
    S: Fn(u32, u32),
{
    let root = bvh.root();
    if root.is_empty() {
        return 0;
    }
    let m = box_mask::<I>(rays, hits, &root.lo, &root.hi, mask);
    if m == 0 {
        return 0;
    }
    let base = stack.len();
    let mut done = 0u64;
    let mut cur: Entry = (root.link, root.count, m);
    loop {
        let (link, count, m) = cur;
        let m = m & !done;
        if m != 0 {
            if count > 0 {
                done |= leaf(hits, link, count, m);
                if mask & !done == 0 {
                    break;
                }
            } else if let Some(node) = bvh.nodes().get(link as usize) {
                // Start loading every child before the box tests decide which are reached
                // (most are, for the packet as a whole).
                for k in 0..WIDTH {
                    if node.link[k] != EMPTY_LINK {
                        if node.count[k] != 0 {
                            soon(node.link[k], node.count[k]);
                        } else if let Some(n) = bvh.nodes().get(node.link[k] as usize) {
                            // A node's two cache lines: boxes from offset 0, links from 96.
                            prefetch(n);
                            prefetch(&n.link);
                        }
                    }
                }
                let (early, key) = lane_vs_node(rays, hits, lead_lane(m), node);
                let mut valid = 0u32;
                for k in 0..WIDTH {
                    valid |= ((node.link[k] != EMPTY_LINK) as u32) << k;
                }
                // SAFETY: `I` is only instantiated for an instruction set the CPU has.
                let culled =
                    if valid & !early != 0 { (unsafe { I::culls4(fr, &node.lo, &node.hi) }) & !early } else { 0 };
                let live = valid & !culled;
                // Inner children the lead lane hits are entered with the whole mask; the
                // others get their exact lanes.
                let mut leaves = 0u32;
                for k in 0..WIDTH {
                    leaves |= ((node.count[k] != 0) as u32) << k;
                }
                let exact = live & !(early & !leaves);
                let masks = child_masks::<I>(rays, hits, node, exact, m);
                // Children with lanes, as (key, entry), sorted near to far.
                let mut ents = [(0f32, (0u32, 0u32, 0u64)); WIDTH];
                let mut n = 0;
                let mut todo = live;
                while todo != 0 {
                    let k = todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    let mk = if exact >> k & 1 != 0 { masks[k] } else { m };
                    if mk != 0 {
                        let e = (key[k], (node.link[k], node.count[k], mk));
                        // Insertion sort on at most four entries.
                        let mut p = n;
                        while p > 0 && ents[p - 1].0 > e.0 {
                            ents[p] = ents[p - 1];
                            p -= 1;
                        }
                        ents[p] = e;
                        n += 1;
                    }
                }
                if n > 0 {
                    for e in ents[1..n].iter().rev() {
                        stack.push(e.1);
                    }
                    cur = ents[0].1;
                    continue;
                }
            }
        }
        if stack.len() <= base {
            break;
        }
        match stack.pop() {
            Some(e) => cur = e,
            None => break,
        }
    }
    stack.truncate(base);
    done
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lead_lane_is_a_central_one_when_active_else_the_first() {
        // Lanes 27, 28, 35, 36: rows 3 and 4, columns 3 and 4 of the 8 × 8 packet.
        assert_eq!(CENTER.count_ones(), 4);
        for lane in [27u32, 28, 35, 36] {
            assert!(CENTER >> lane & 1 == 1, "lane {lane}");
        }
        assert_eq!(lead_lane(u64::MAX), 27);
        assert_eq!(lead_lane(1 << 5 | 1 << 36), 36);
        assert_eq!(lead_lane(1 << 5 | 1 << 40), 5);
        assert_eq!(lead_lane(1 << 63), 63);
    }
}

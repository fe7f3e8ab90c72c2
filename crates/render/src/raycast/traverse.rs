//! Packet traversal of a pair-layout BVH: masked, ordered, with early hit and frustum culling.
//!
//! The scheme is the BVH packet traversal of Wald, Boulos & Shirley 2007 ("Ray Tracing
//! Deformable Scenes Using Dynamic Bounding Volume Hierarchies") with the active-ray mask of
//! Overbeck, Ramamoorthi & Mark 2008 ("Large Ray Packets for Real-time Whitted Ray
//! Tracing"). A node is entered with the mask of lanes that may hit it; for each child:
//!
//! 1. *early hit*: if the first active lane hits the child box, descend with the whole mask
//!    (one scalar box test — the common case near the root for coherent rays);
//! 2. *frustum cull*: if the box is outside one of the packet's beam planes, no lane hits;
//! 3. otherwise test every active lane in SIMD and descend with the lanes that hit.
//!
//! Lane tests clip against each lane's current closest hit, so subtrees behind what the
//! packet already sees drop out (occlusion). Children are visited near to far along the
//! first active lane; leaves get an exact lane mask before their primitives are tested. Box
//! tests use the robust slab test of Ize 2013 ("Robust BVH Ray Traversal"): the exit distance
//! is scaled up by 1 + 2⁻²⁰ (more than Ize's 1 + 2γ₃ and than the triangle tie window), so
//! rounding never loses a hit.

use super::bvh::{Bvh, Child};
use super::packet::{chunk_bits, Frustum, Hits, Rays, CHUNK, CHUNKS};

/// 1 + 2⁻²⁰: above 1 + 2γ₃ (γ₃ = 3ε / (1 − 3ε), ε = 2⁻²⁴) and the tie window.
const ROBUST: f32 = 1.0 + 1.0 / (1u32 << 20) as f32;

/// A pending subtree: (link, primitive count, lane mask).
pub(crate) type Entry = (u32, u32, u64);

#[inline(always)]
fn mn(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn mx(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// Lanes of `mask` whose interval meets the box.
#[inline(always)]
pub(crate) fn box_mask(rays: &Rays, hits: &Hits, lo: &[f32; 3], hi: &[f32; 3], mask: u64) -> u64 {
    let mut out = 0u64;
    for c in 0..CHUNKS {
        let bits = chunk_bits(mask, c);
        if bits == 0 {
            continue;
        }
        let (ox, oy, oz) = (&rays.o[0][c], &rays.o[1][c], &rays.o[2][c]);
        let (rx, ry, rz) = (&rays.r[0][c], &rays.r[1][c], &rays.r[2][c]);
        let (tmin, tmax) = (&hits.tmin[c], &hits.t[c]);
        let mut m = 0u64;
        for j in 0..CHUNK {
            let x0 = (lo[0] - ox[j]) * rx[j];
            let x1 = (hi[0] - ox[j]) * rx[j];
            let y0 = (lo[1] - oy[j]) * ry[j];
            let y1 = (hi[1] - oy[j]) * ry[j];
            let z0 = (lo[2] - oz[j]) * rz[j];
            let z1 = (hi[2] - oz[j]) * rz[j];
            let near = mx(mx(mn(x0, x1), mn(y0, y1)), mx(mn(z0, z1), tmin[j]));
            let far = mn(mn(mx(x0, x1), mx(y0, y1)), mn(mx(z0, z1), tmax[j]));
            m |= ((near <= far * ROBUST) as u64) << j;
        }
        out |= (m & bits) << (c * CHUNK);
    }
    out
}

/// Does lane `i` meet the box?
#[inline(always)]
fn lane_hits(rays: &Rays, hits: &Hits, i: usize, lo: &[f32; 3], hi: &[f32; 3]) -> bool {
    let (c, j) = (i / CHUNK, i % CHUNK);
    let mut near = hits.tmin[c][j];
    let mut far = hits.t[c][j];
    for a in 0..3 {
        let t0 = (lo[a] - rays.o[a][c][j]) * rays.r[a][c][j];
        let t1 = (hi[a] - rays.o[a][c][j]) * rays.r[a][c][j];
        near = mx(near, mn(t0, t1));
        far = mn(far, mx(t0, t1));
    }
    near <= far * ROBUST
}

/// The lanes that may hit `child` (a superset after an early hit) and its sort key.
#[inline(always)]
fn child_mask(child: &Child, rays: &Rays, hits: &Hits, fr: &Frustum, mask: u64, first: usize) -> u64 {
    if !child.is_leaf() && lane_hits(rays, hits, first, &child.lo, &child.hi) {
        return mask;
    }
    if fr.culls(&child.lo, &child.hi) {
        return 0;
    }
    box_mask(rays, hits, &child.lo, &child.hi, mask)
}

/// Distance of the box center along the first active lane (orders near before far).
#[inline(always)]
fn key(child: &Child, rays: &Rays, first: usize) -> f32 {
    let o = rays.origin(first);
    let d = rays.dir(first);
    let mut k = 0.0;
    for a in 0..3 {
        k += (0.5 * (child.lo[a] + child.hi[a]) - o[a]) * d[a];
    }
    k
}

/// Traverses `bvh` with the lanes of `mask`, calling `leaf(hits, first, count, lanes)` for
/// each leaf reached with the exact lanes that meet its box. `leaf` returns lanes it has
/// finished (any-hit queries), which then leave the traversal; the union is returned.
/// `stack` is scratch space, used above its current length and restored.
#[inline(always)]
pub(crate) fn traverse<F>(
    bvh: &Bvh,
    rays: &Rays,
    hits: &mut Hits,
    fr: &Frustum,
    mask: u64,
    stack: &mut Vec<Entry>,
    mut leaf: F,
) -> u64
where
    F: FnMut(&mut Hits, u32, u32, u64) -> u64,
{
    let root = &bvh.root;
    let m = box_mask(rays, hits, &root.lo, &root.hi, mask);
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
            } else if let Some(pair) = bvh.pairs.get(link as usize) {
                let first = m.trailing_zeros() as usize;
                let [a, b] = &pair.0;
                let ma = child_mask(a, rays, hits, fr, m, first);
                let mb = child_mask(b, rays, hits, fr, m, first);
                let ea: Entry = (a.link, a.count, ma);
                let eb: Entry = (b.link, b.count, mb);
                match (ma != 0, mb != 0) {
                    (true, true) => {
                        let (near, far) = if key(a, rays, first) <= key(b, rays, first) { (ea, eb) } else { (eb, ea) };
                        stack.push(far);
                        cur = near;
                        continue;
                    }
                    (true, false) => {
                        cur = ea;
                        continue;
                    }
                    (false, true) => {
                        cur = eb;
                        continue;
                    }
                    (false, false) => {}
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

//! The geometry stage: transform each vertex once, classify triangles with outcodes, clip
//! the few that need it, set up the rest.
//!
//! Per draw piece the referenced vertex span is transformed by one `clip_from_local`
//! matrix into flat, reused arrays (clip position, outcode, snapped window position), so a
//! vertex shared by six triangles is transformed and projected once. Each triangle then
//! costs three array reads, an AND and an OR of outcodes (Cohen–Sutherland's trivial
//! reject/accept), and setup. Only triangles crossing the near/far planes or the guard band
//! go through the homogeneous Sutherland–Hodgman clipper ([`crate::clip`]).

use glam::{Mat4, Vec3, Vec4};

use crate::clip::{self, BAD, GUARD, VIEW_BITS};
use crate::setup::{setup_into, Outcome, SnappedVertex, Tri, Viewport};
use crate::stats::FrameStats;

/// Where a draw piece's triangles come from.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Source<'a> {
    /// An indexed mesh under one matrix; `ids`, when given, maps each triangle of `indices`
    /// to the triangle number its ID is made from (meshlets keep the original IDs).
    Mesh { positions: &'a [Vec3], indices: &'a [u32], clip_from_local: Mat4, ids: Option<&'a [u32]> },
    /// Raw clip-space triangles (tests and tools).
    Clip(&'a [[Vec4; 3]]),
}

/// One item of the draw list, resolved.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Item<'a> {
    pub src: Source<'a>,
    /// ID of the source's triangle 0 (IDs are `first_id + triangle index`).
    pub first_id: u32,
    /// Total triangles in the source (to know when a piece is the whole mesh).
    pub source_triangles: u32,
}

/// A contiguous triangle range of one item.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Piece {
    pub item: u32,
    pub start: u32,
    pub count: u32,
}

/// Reused per-vertex arrays.
#[derive(Debug, Default)]
struct VertexCache {
    clip: Vec<Vec4>,
    code: Vec<u8>,
    snapped: Vec<SnappedVertex>,
}

/// Output of the geometry stage for one chunk of the draw list.
#[derive(Debug, Default)]
pub(crate) struct Chunk {
    verts: VertexCache,
    /// Set-up triangles in submission order.
    pub tris: Vec<Tri>,
    /// Per tile: indices into `tris`.
    pub bins: Vec<Vec<u32>>,
    /// "Covered some pixel" flags of triangles spanning several tiles.
    pub multi: Vec<std::sync::atomic::AtomicBool>,
    /// Counters of this chunk.
    pub stats: FrameStats,
}

const NONE: SnappedVertex = SnappedVertex { x: 0, y: 0, z: 0.0 };

impl Chunk {
    /// Runs the geometry stage over `pieces`.
    #[inline(never)] // a stage of its own in profiles
    pub fn process(&mut self, items: &[Item], pieces: &[Piece], vp: &Viewport, cull: bool) {
        self.tris.clear();
        self.stats = FrameStats::default();
        for p in pieces {
            let item = &items[p.item as usize];
            match item.src {
                Source::Mesh { positions, indices, clip_from_local, ids } => {
                    let idx = &indices[3 * p.start as usize..3 * (p.start + p.count) as usize];
                    let (lo, hi) = if p.count == item.source_triangles {
                        (0, positions.len())
                    } else {
                        let lo = idx.iter().copied().min().unwrap_or(0) as usize;
                        let hi = idx.iter().copied().max().map_or(0, |m| m as usize + 1);
                        (lo, hi)
                    };
                    self.transform(&positions[lo..hi], &clip_from_local, vp);
                    let first_id = item.first_id.wrapping_add(p.start);
                    let ids = ids.map(|m| &m[p.start as usize..(p.start + p.count) as usize]);
                    for (k, t) in idx.chunks_exact(3).enumerate() {
                        let v = [t[0] as usize - lo, t[1] as usize - lo, t[2] as usize - lo];
                        let id = match ids {
                            Some(m) => item.first_id.wrapping_add(m[k]),
                            None => first_id.wrapping_add(k as u32),
                        };
                        self.triangle(v, id, vp, cull);
                    }
                }
                Source::Clip(tris) => {
                    let tris = &tris[p.start as usize..(p.start + p.count) as usize];
                    self.load_clip(tris, vp);
                    let first_id = item.first_id.wrapping_add(p.start);
                    for k in 0..tris.len() {
                        let v = [3 * k, 3 * k + 1, 3 * k + 2];
                        self.triangle(v, first_id.wrapping_add(k as u32), vp, cull);
                    }
                }
            }
        }
    }

    #[inline(never)] // per-vertex work, separate in profiles
    fn transform(&mut self, positions: &[Vec3], m: &Mat4, vp: &Viewport) {
        let vc = &mut self.verts;
        vc.clip.clear();
        vc.clip.extend(positions.iter().map(|p| *m * p.extend(1.0)));
        vc.code.resize(positions.len(), 0);
        vc.snapped.resize(positions.len(), NONE);
        for ((c, code), s) in vc.clip.iter().zip(vc.code.iter_mut()).zip(vc.snapped.iter_mut()) {
            (*code, *s) = Self::classify(*c, vp);
        }
    }

    fn load_clip(&mut self, tris: &[[Vec4; 3]], vp: &Viewport) {
        let vc = &mut self.verts;
        vc.clip.clear();
        vc.clip.extend(tris.iter().flatten());
        vc.code.clear();
        vc.snapped.clear();
        for c in &vc.clip {
            let (code, s) = Self::classify(*c, vp);
            vc.code.push(code);
            vc.snapped.push(s);
        }
    }

    /// Outcode and (inside the guard band) the snapped window position of a vertex.
    #[inline(always)]
    fn classify(c: Vec4, vp: &Viewport) -> (u8, SnappedVertex) {
        let code = vp.outcode(c);
        if code & GUARD != 0 {
            return (code, NONE);
        }
        match vp.project(c) {
            Some(s) => (code, s),
            None => (code | GUARD, NONE),
        }
    }

    #[inline(always)]
    fn triangle(&mut self, v: [usize; 3], id: u32, vp: &Viewport, cull: bool) {
        let st = &mut self.stats;
        st.triangles_in += 1;
        let c = [self.verts.code[v[0]], self.verts.code[v[1]], self.verts.code[v[2]]];
        let and = c[0] & c[1] & c[2];
        let or = c[0] | c[1] | c[2];
        if and & VIEW_BITS != 0 || or & BAD != 0 {
            st.trivially_rejected += 1;
            return;
        }
        if or & GUARD != 0 {
            self.clipped(v, id, vp, cull);
            return;
        }
        let s = [self.verts.snapped[v[0]], self.verts.snapped[v[1]], self.verts.snapped[v[2]]];
        let o = setup_into(s, id, cull, vp, &mut self.tris);
        self.count(o);
    }

    #[inline(always)]
    fn count(&mut self, o: Outcome) {
        match o {
            Outcome::Ready => {}
            Outcome::BackFace => self.stats.backface_culled += 1,
            Outcome::Degenerate => self.stats.degenerate += 1,
            Outcome::TooSmall => self.stats.too_small += 1,
        }
    }

    #[cold]
    fn clipped(&mut self, v: [usize; 3], id: u32, vp: &Viewport, cull: bool) {
        let c = [self.verts.clip[v[0]], self.verts.clip[v[1]], self.verts.clip[v[2]]];
        // Facing from the homogeneous determinant: valid before clipping, whatever the w's.
        let det = clip::facing_det(c);
        if !det.is_finite() {
            self.stats.trivially_rejected += 1;
            return;
        }
        if det == 0.0 {
            self.stats.degenerate += 1;
            return;
        }
        if cull && det < 0.0 {
            self.stats.backface_culled += 1;
            return;
        }
        self.stats.clipped += 1;
        let poly = clip::clip_triangle(c, vp.gx, vp.gy);
        if poly.len() < 3 {
            return;
        }
        let mut s = [NONE; clip::MAX_POLYGON];
        for (o, cv) in s.iter_mut().zip(poly.vertices()) {
            // w > 0 after near/far clipping, except for degenerate input (w = 0 points).
            match (cv.pos.w > 0.0).then(|| vp.project(cv.pos)).flatten() {
                Some(p) => *o = p,
                None => return,
            }
        }
        for i in 1..poly.len() - 1 {
            self.stats.clip_output += 1;
            // Facing was decided above; each fan piece is oriented by its own area.
            let o = setup_into([s[0], s[i], s[i + 1]], id, false, vp, &mut self.tris);
            self.count(o);
        }
    }
}

/// Splits the items into `n` chunks of about equal triangle counts, in order.
pub(crate) fn split(items: &[(u32, u32, u32)], n: usize, out: &mut Vec<Vec<Piece>>) {
    let n = n.max(1);
    out.resize_with(n, Vec::new);
    out.truncate(n);
    for c in out.iter_mut() {
        c.clear();
    }
    let total: u64 = items.iter().map(|i| i.2 as u64).sum();
    let quota = total.div_ceil(n as u64).max(1);
    let (mut chunk, mut filled) = (0usize, 0u64);
    for (k, &(_, start, count)) in items.iter().enumerate() {
        let (mut s, mut left) = (start, count);
        while left > 0 {
            let room = (quota - filled).min(left as u64) as u32;
            out[chunk].push(Piece { item: k as u32, start: s, count: room });
            s += room;
            left -= room;
            filled += room as u64;
            if filled >= quota && chunk + 1 < n {
                chunk += 1;
                filled = 0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_keeps_order_and_balances() {
        let items = [(0, 0, 10), (0, 5, 3), (0, 0, 0), (0, 2, 7)];
        let mut out = Vec::new();
        split(&items, 4, &mut out);
        assert_eq!(out.len(), 4);
        let flat: Vec<_> = out.iter().flatten().map(|p| (p.item, p.start, p.count)).collect();
        let total: u32 = flat.iter().map(|p| p.2).sum();
        assert_eq!(total, 20);
        for c in &out {
            assert!(c.iter().map(|p| p.count).sum::<u32>() <= 5);
        }
        // Contiguous, in submission order.
        assert_eq!(flat[0], (0, 0, 5));
        assert_eq!(flat[1], (0, 5, 5));
        assert_eq!(flat[2], (1, 5, 3));
    }
}

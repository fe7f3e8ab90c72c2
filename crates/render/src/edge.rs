//! The set-up triangle record and its fixed-point edge functions, with the fill rule.
//!
//! Pineda, "A Parallel Algorithm for Polygon Rasterization" (SIGGRAPH 1988): each edge
//! a→b of a triangle defines `E(p) = (b−a) × (p−a)`, positive on the inside of a
//! positively oriented triangle; a pixel is covered when its center gives `E ≥ 0` on all
//! three edges, and E steps incrementally (one add per pixel and edge). Vertices are snapped
//! to [`SUBPIXEL_BITS`] fractional bits, so on these integers the test is exact: two
//! triangles sharing an edge never both cover a center, nor both miss one.
//!
//! # Fill rule: left and bottom edges own ties
//!
//! A center exactly on an edge (`E = 0`) must belong to exactly one of the two triangles
//! that share the edge. The rule chosen is llvmpipe's (Mesa's software OpenGL rasterizer),
//! so that both draw the same pixels: the edge belongs to the triangle for which it is a
//! LEFT or a BOTTOM edge as seen in the image. In y-down window coordinates with positive
//! area, an edge running up the screen (`dy < 0`) has the triangle on its right — a left
//! edge; a horizontal edge running right to left (`dy = 0, dx < 0`) has the triangle above
//! it — a bottom edge. See [`left_bottom_owns_ties`]. Other edges get a bias of −1, which
//! turns `E ≥ 0` into `E > 0` on integers. Exactly horizontal street cameras put whole
//! pixel columns on vertical building edges, so this rule decides thousands of pixels per
//! frame.
//!
//! Edge values over 8×8 blocks are set up in i32 where they fit ([`FastEdges`], nearly
//! every triangle) and from the i64 functions otherwise ([`wide_block`]).

/// Fractional bits of snapped coordinates.
pub(crate) const SUBPIXEL_BITS: u32 = 8;
/// One pixel in fixed point.
pub(crate) const ONE: i32 = 1 << SUBPIXEL_BITS;
use crate::tiling::BLOCK;

/// A set-up triangle, ready for binning and rasterization.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tri {
    /// Snapped x of the vertices (oriented so the signed area is positive, y down).
    pub x: [i32; 3],
    /// Snapped y (down).
    pub y: [i32; 3],
    /// Depth at vertex 0.
    pub z0: f32,
    /// Depth change per fixed-point unit of x.
    pub zx: f32,
    /// Depth change per fixed-point unit of y.
    pub zy: f32,
    /// Depth of the nearest vertex: no pixel's depth is taken nearer (see
    /// [`Tri::depth_at`]).
    pub zmin: f32,
    /// The ID written.
    pub id: u32,
    /// Pixel-center bounding box, inclusive, clamped to the screen: x0, y0, x1, y1.
    pub bbox: [u16; 4],
    /// Index of this triangle's "covered" flag when it spans several tiles (else u32::MAX).
    pub multi: u32,
}

impl Tri {
    /// Window depth at the center of pixel row `py`, column offset zero from vertex 0.
    #[inline(always)]
    pub(crate) fn depth_row(&self, py: i32) -> f32 {
        self.z0 + self.zy * (((py << SUBPIXEL_BITS) + ONE / 2 - self.y[0]) as f32)
    }

    /// Window depth at the center of pixel column `px` of a row whose [`Tri::depth_row`] is
    /// `zrow`, no nearer than the nearest vertex.
    ///
    /// Exactly evaluated, the plane at a pixel center inside the triangle lies between its
    /// vertices' depths. In f32, a plane evaluated far from its vertices (a sliver seen edge
    /// on, a vertex far off screen) can come out below the nearest one by more than box
    /// tests allow for; clamping keeps every depth the rasterizer writes at or behind the
    /// triangle's nearest vertex, which the box tests of culling rely on.
    #[inline(always)]
    pub(crate) fn depth_at(&self, zrow: f32, px: i32) -> f32 {
        no_nearer(self.zmin, zrow + self.zx * (((px << SUBPIXEL_BITS) + ONE / 2 - self.x[0]) as f32))
    }

    /// True when the plane gives a number (not NaN) at every pixel the rasterizer can reach,
    /// which the vector kernels take for granted: with `z0`, `zx` and `zy` at most 2^90 in
    /// magnitude and a pixel center's offset from vertex 0 an i32 (below 2^32 fixed-point
    /// units), each product is below 2^122 and each sum below 2^124, far from f32's overflow,
    /// so no infinity can arise to meet another of the other sign. Every plane set-up makes
    /// is such (window depths lie in [0, 1] and the area is at least one unit); a triangle
    /// with any other plane is drawn by the scalar path, where a NaN depth is never written.
    #[inline(always)]
    pub(crate) fn depths_are_numbers(&self) -> bool {
        const LIMIT: f32 = (1u128 << 90) as f32;
        // Written as `<=` so that NaN coefficients fail.
        self.z0.abs() <= LIMIT && self.zx.abs() <= LIMIT && self.zy.abs() <= LIMIT
    }

    /// A lower bound of the depths the rasterizer computes over the pixel centers of the
    /// screen rectangle `[x0, y0, x1, y1]` (inclusive): the plane is affine, so its minimum
    /// is at a corner; the rounding that evaluating it at a pixel may add is subtracted, and
    /// the result raised to `zmin` like every pixel's depth ([`Tri::depth_at`]).
    #[inline]
    pub(crate) fn plane_min(&self, rect: [i32; 4]) -> f32 {
        self.plane_bounds(rect).0
    }

    /// Lower and upper bounds of the depths computed over the pixel centers of the screen
    /// rectangle `[x0, y0, x1, y1]` (inclusive): the plane's, each widened by the rounding that
    /// evaluating the plane at a pixel ([`Tri::depth_row`], [`Tri::depth_at`]) may add: every
    /// depth the rasterizer computes for a pixel of the rectangle lies between them.
    #[inline]
    pub(crate) fn plane_bounds(&self, [x0, y0, x1, y1]: [i32; 4]) -> (f32, f32) {
        let cx = |px: i32| self.zx * ((px << SUBPIXEL_BITS) + ONE / 2 - self.x[0]) as f32;
        let cy = |py: i32| self.zy * ((py << SUBPIXEL_BITS) + ONE / 2 - self.y[0]) as f32;
        let (a0, a1, b0, b1) = (cx(x0), cx(x1), cy(y0), cy(y1));
        let err = 8.0 * f32::EPSILON * (self.z0.abs() + max(a0.abs(), a1.abs()) + max(b0.abs(), b1.abs())) + 1e-7;
        let (lo, hi) = (self.z0 + min(a0, a1) + min(b0, b1) - err, self.z0 + max(a0, a1) + max(b0, b1) + err);
        // The clamp of `depth_at` raises depths to `zmin`.
        (max(lo, self.zmin), max(hi, self.zmin))
    }
}

/// `z`, or `zmin` when that is larger: the rasterizer's clamp of a depth to a triangle's
/// nearest vertex. A NaN `z` stays NaN (it then fails every depth test), exactly as
/// `maxps(zmin, z)` does, which the vector kernels use.
#[inline(always)]
pub(crate) fn no_nearer(zmin: f32, z: f32) -> f32 {
    if zmin > z {
        zmin
    } else {
        z
    }
}

/// The smaller of two finite floats, as one `minss`. `f32::min` also orders NaN, which costs
/// three more instructions on SSE; a set-up triangle's plane (`z0`, `zx`, `zy`) is finite
/// (its vertices passed projection's finiteness test and its area is at least one fixed-point
/// unit), so the coarse depth tests never meet NaN.
#[inline(always)]
pub(crate) fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// The larger of two finite floats, as one `maxss` (see [`min`]).
#[inline(always)]
pub(crate) fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// The fill rule's tie break: true when an edge with direction `(dx, dy)` (fixed point, y
/// down, triangle positively oriented) owns the pixel centers exactly on it — a LEFT edge
/// (`dy < 0`) or a BOTTOM edge (`dy = 0, dx < 0`), llvmpipe's convention (see the module
/// doc).
#[inline(always)]
pub(crate) fn left_bottom_owns_ties(dx: i64, dy: i64) -> bool {
    dy < 0 || (dy == 0 && dx < 0)
}

/// One edge function: `E(px, py) = a·px + b·py + c` at pixel center (px, py), fill-rule
/// bias included, so that "covered" is `E ≥ 0`.
#[derive(Clone, Copy)]
pub(crate) struct Edge {
    pub a: i64,
    pub b: i64,
    pub c: i64,
}

/// The three edge functions of a triangle.
#[inline(always)]
pub(crate) fn edges(t: &Tri) -> [Edge; 3] {
    let half = (ONE / 2) as i64;
    let one = ONE as i64;
    std::array::from_fn(|i| {
        let j = (i + 1) % 3;
        let (ax, ay) = (t.x[i] as i64, t.y[i] as i64);
        let (dx, dy) = (t.x[j] as i64 - ax, t.y[j] as i64 - ay);
        let bias = !left_bottom_owns_ties(dx, dy) as i64;
        Edge { a: -dy * one, b: dx * one, c: dx * (half - ay) - dy * (half - ax) - bias }
    })
}

/// True when some pixel center of the triangle's bounding box is covered (used by setup
/// for tiny boxes).
#[allow(clippy::needless_range_loop)] // edge k of two arrays
pub(crate) fn covers_any(t: &Tri) -> bool {
    let e = edges(t);
    let [x0, y0, x1, y1] = t.bbox.map(|v| v as i64);
    // The edge values at the box's first pixel center, stepped from there (exact integers, so
    // the same values as evaluated at each center): a center is covered where none is negative.
    let mut row: [i64; 3] = std::array::from_fn(|k| e[k].a * x0 + e[k].b * y0 + e[k].c);
    for _ in y0..=y1 {
        let mut v = row;
        for _ in x0..=x1 {
            if (v[0] | v[1] | v[2]) >= 0 {
                return true;
            }
            for k in 0..3 {
                v[k] += e[k].a;
            }
        }
        for k in 0..3 {
            row[k] += e[k].b;
        }
    }
    false
}

/// True when the triangle covers no pixel center of the inclusive pixel rectangle (a
/// conservative test: false means "maybe").
pub(crate) fn misses_rect(t: &Tri, r: [i32; 4]) -> bool {
    let e = edges(t);
    let (w, h) = ((r[2] - r[0]) as i64, (r[3] - r[1]) as i64);
    e.iter().any(|e| {
        let e00 = e.a * r[0] as i64 + e.b * r[1] as i64 + e.c;
        e00 + e.a.max(0) * w + e.b.max(0) * h < 0
    })
}

/// How the kernel is to run one block.
pub(crate) enum BlockSetup {
    /// Outside an edge: nothing to do.
    Outside,
    /// Edge values in i32 (an edge the block is inside of is all zeros).
    Narrow(BlockEdges),
    /// Values too big for i32: per pixel on i64, from these values at the rectangle's first
    /// pixel (rare: vertices thousands of pixels away).
    Wide([i64; 3]),
}

/// Edge values at a block's first pixel and their steps along x and y, as i32; an edge the
/// block is entirely inside of is all zeros (inside everywhere).
pub(crate) struct BlockEdges {
    pub e: [i32; 3],
    pub a: [i32; 3],
    pub b: [i32; 3],
}

/// Block setup from the i64 edge functions over the rectangle `[rx0, ry0, rx1, ry1]`: a
/// block whose values fit i32 goes to the kernels when `narrow` allows it.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // edge k of several arrays
pub(crate) fn wide_block(e: &[Edge; 3], [rx0, ry0, rx1, ry1]: [i32; 4], narrow: bool) -> BlockSetup {
    let (w, h) = ((rx1 - rx0) as i64, (ry1 - ry0) as i64);
    let mut fits = true;
    let mut k32 = BlockEdges { e: [0; 3], a: [0; 3], b: [0; 3] };
    let mut e00 = [0i64; 3];
    for k in 0..3 {
        let v = e[k].a * rx0 as i64 + e[k].b * ry0 as i64 + e[k].c;
        e00[k] = v;
        let lo = v + e[k].a.min(0) * w + e[k].b.min(0) * h;
        let hi = v + e[k].a.max(0) * w + e[k].b.max(0) * h;
        if hi < 0 {
            return BlockSetup::Outside;
        }
        if lo < 0 {
            // The edge crosses the block: tested per pixel. Wrapping i32 steps are exact
            // modulo 2^32, so values that fit i32 come out exact.
            fits &= lo >= i32::MIN as i64 && hi <= i32::MAX as i64;
            (k32.e[k], k32.a[k], k32.b[k]) = (v as i32, e[k].a as i32, e[k].b as i32);
        }
    }
    if fits && narrow {
        BlockSetup::Narrow(k32)
    } else {
        BlockSetup::Wide(e00)
    }
}

/// The edge functions of a triangle whose values fit i32 over every 8×8 block its
/// bounding box (clipped to the tile) touches: the common case, triangles up to about a
/// hundred pixels across.
pub(crate) struct FastEdges {
    /// The first block's corner (screen pixels).
    corner: [i32; 2],
    /// Values at the first block's corner.
    e: [i32; 3],
    /// Steps per pixel along x and y.
    a: [i32; 3],
    b: [i32; 3],
    /// Lowest and highest offset from a block corner's value over the block's 8×8 pixels.
    lo: [i32; 3],
    hi: [i32; 3],
}

impl FastEdges {
    /// `None` when some value over the block-aligned box of `[x0, y0, x1, y1]`, or the
    /// spread of an edge's values over one block, leaves i32 (long slivers: a steep edge
    /// over a box one block wide), so that every edge value over the box fits i32.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // edge k of several arrays
    pub(crate) fn new(e: &[Edge; 3], [x0, y0, x1, y1]: [i32; 4]) -> Option<Self> {
        let (ax0, ay0) = ((x0 & !(BLOCK - 1)) as i64, (y0 & !(BLOCK - 1)) as i64);
        let (w, h) = ((x1 | (BLOCK - 1)) as i64 - ax0, (y1 | (BLOCK - 1)) as i64 - ay0);
        let corner = [ax0 as i32, ay0 as i32];
        let mut f = FastEdges { corner, e: [0; 3], a: [0; 3], b: [0; 3], lo: [0; 3], hi: [0; 3] };
        let m = (BLOCK - 1) as i64;
        for k in 0..3 {
            // Affine: the extremes over the box are at its corners.
            let v = e[k].a * ax0 + e[k].b * ay0 + e[k].c;
            let lo = v + e[k].a.min(0) * w + e[k].b.min(0) * h;
            let hi = v + e[k].a.max(0) * w + e[k].b.max(0) * h;
            let (block_lo, block_hi) = (e[k].a.min(0) * m + e[k].b.min(0) * m, e[k].a.max(0) * m + e[k].b.max(0) * m);
            let fits = |x: i64| x >= i32::MIN as i64 && x <= i32::MAX as i64;
            if !(fits(lo) && fits(hi) && fits(block_lo) && fits(block_hi)) {
                return None;
            }
            f.e[k] = v as i32;
            f.a[k] = e[k].a as i32;
            f.b[k] = e[k].b as i32;
            (f.lo[k], f.hi[k]) = (block_lo as i32, block_hi as i32);
        }
        Some(f)
    }

    /// Setup of the block with corner `[bx, by]` and rectangle `[rx0, ry0, ...]` inside
    /// it: whole blocks (not their parts inside the box) decide "outside" and "inside an
    /// edge"; a block skipped or an edge dropped that way is so for its part inside the box
    /// too, so the pixels drawn are the same. Every result is a value over the box, so it
    /// fits i32 (a product on the way may wrap; see below).
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // edge k of several arrays
    pub(crate) fn block(&self, [rx0, ry0, _, _]: [i32; 4], [bx, by]: [i32; 2]) -> BlockSetup {
        let mut k32 = BlockEdges { e: [0; 3], a: [0; 3], b: [0; 3] };
        let (dx, dy) = (bx - self.corner[0], by - self.corner[1]);
        // A step times an offset can leave i32 (a long steep edge) while the value it leads to
        // cannot: wrapping arithmetic is exact modulo 2^32, so every result that fits is exact.
        let value = |k: usize, x: i32, y: i32, from: i32| {
            from.wrapping_add(self.a[k].wrapping_mul(x)).wrapping_add(self.b[k].wrapping_mul(y))
        };
        for k in 0..3 {
            let at = value(k, dx, dy, self.e[k]);
            if at + self.hi[k] < 0 {
                return BlockSetup::Outside;
            }
            if at + self.lo[k] < 0 {
                // The edge crosses the block: tested per pixel, from the rectangle's first
                // pixel.
                let e = value(k, rx0 - bx, ry0 - by, at);
                (k32.e[k], k32.a[k], k32.b[k]) = (e, self.a[k], self.b[k]);
            }
        }
        BlockSetup::Narrow(k32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `covers_any` says whether some pixel center of the box is covered exactly as the
    /// edge functions evaluated at each center do, on tiny triangles of both sizes of box
    /// setup gives it (a pixel or two across) and on larger boxes, ties on the centers
    /// included (vertices on the fixed-point grid of the centers).
    #[test]
    fn covers_any_equals_each_center_tested() {
        let mut rng = sightline_scene::rng::Rng::new(11);
        let (mut covered, mut missed) = (0, 0);
        for n in 0..20_000 {
            let span = [1.5, 3.0, 8.0][n % 3] * ONE as f32;
            // Every fourth triangle on the half-pixel grid, so centers fall on its edges.
            let snap = |v: f32| if n % 4 == 0 { (v / (ONE / 2) as f32) as i32 * (ONE / 2) } else { v as i32 };
            let mut x: [i32; 3] = std::array::from_fn(|_| snap(100.0 * ONE as f32 + rng.range(0.0, span)));
            let mut y: [i32; 3] = std::array::from_fn(|_| snap(50.0 * ONE as f32 + rng.range(0.0, span)));
            let area = (x[1] - x[0]) as i64 * (y[2] - y[0]) as i64 - (x[2] - x[0]) as i64 * (y[1] - y[0]) as i64;
            if area == 0 {
                continue;
            }
            if area < 0 {
                x.swap(1, 2);
                y.swap(1, 2);
            }
            // The pixels whose centers the triangle's extent could hold.
            let pixel = |v: Option<&i32>| (v.copied().unwrap_or(0) >> SUBPIXEL_BITS) as u16;
            let bbox = [pixel(x.iter().min()), pixel(y.iter().min()), pixel(x.iter().max()), pixel(y.iter().max())];
            let t = Tri { x, y, z0: 0.0, zx: 0.0, zy: 0.0, zmin: 0.0, id: 1, bbox, multi: u32::MAX };
            let e = edges(&t);
            let [x0, y0, x1, y1] = t.bbox.map(|v| v as i64);
            let each = (y0..=y1).any(|py| (x0..=x1).any(|px| e.iter().all(|e| e.a * px + e.b * py + e.c >= 0)));
            assert_eq!(covers_any(&t), each, "triangle {x:?} {y:?} in box {:?}", t.bbox);
            *if each { &mut covered } else { &mut missed } += 1;
        }
        assert!(covered > 1_000 && missed > 1_000, "covered {covered}, missed {missed}");
    }
}

//! The painter's algorithm: depth sort with the Newell–Newell–Sancha tests, and the plain
//! centroid sort it improves on.
//!
//! Newell, Newell & Sancha, "A Solution to the Hidden Surface Problem" (ACM National
//! Conference, 1972), as taught by Foley, van Dam, Feiner & Hughes, *Computer Graphics:
//! Principles and Practice* (2nd ed., 1990), §15.5: draw polygons from the farthest to the
//! nearest, each over what is already there, with no depth buffer. Sorting by one depth
//! per polygon is not enough (long polygons, interpenetration, cycles), so the order is
//! made right pair by pair:
//!
//! 1. Clip every front-facing triangle to the view frustum and sort by farthest depth (the
//!    largest NDC z; the lab's `polygon` module says why the tests run in NDC).
//! 2. Let P be the polygon at the head of the list (the one to draw next). Before drawing
//!    it, compare it with every polygon Q whose depth range overlaps P's (Q's farthest
//!    point is farther than P's nearest); P may be drawn when, for every such Q, one test
//!    shows that P does not obscure Q, cheapest first: (1) their x extents are disjoint,
//!    (2) their y extents are disjoint, (3) P lies entirely behind Q's plane (on the side
//!    away from the viewer), (4) Q lies entirely in front of P's plane, (5) their
//!    projections on the screen do not overlap.
//! 3. If every test fails for some Q, P may obscure it. If Q could be drawn first — Q is
//!    entirely behind P's plane (3′), or P entirely in front of Q's plane (4′) — Q is moved
//!    to the head of the list, marked, and the tests start over with Q as P.
//! 4. Otherwise the two interpenetrate, or a polygon that was already moved must move
//!    again: a cycle (three sticks each lying over the next). One is split by the plane of
//!    the other — Q by P's plane when Q crosses it, else P by Q's — and the pieces, which
//!    now each pass a test against the other polygon, go back into the list by depth. A
//!    cycle of polygons that are pairwise separable by their planes has no such split;
//!    then the larger of the two on screen is cut in half across its longer screen extent.
//!
//! Pieces keep their parent's triangle ID and plane. The whole triangles are drawn from
//! the rasterizer's own set-up records and pieces through the same setup (the lab's `scan` module),
//! so a right order gives the z-buffer's pixels.
//!
//! The number of pair tests grows with the pairs whose depth ranges overlap: up to n² (a
//! street view, where the ground overlaps everything in depth). On city views most pairs
//! are told apart by their screen extents at once (a 10^5-triangle city, seen whole, sorts
//! in about 0.3 s with 1.2·10^7 pair tests); the soup size ([`LIMIT`]), the pair comparisons
//! ([`COMPARISON_LIMIT`]) and the splits ([`split_limit`]) are bounded, so no input runs
//! for an hour or loops for ever: it ends in an error naming the bound instead.

use glam::{DVec3, DVec4};
use sightline_scene::Camera;

use super::polygon::{self, EPS};
use super::scan::{self, ScreenTriangles, CULL_BACK_FACES};
use super::{Counters, Soup};
use crate::setup::Viewport;
use crate::{Error, Framebuffer, Result};

/// Most triangles the painter's algorithm takes: about 10^5, with room for the scene
/// generators' overshoot (`city:100000` has 102,570 triangles). Sorting a 10^5-triangle
/// city takes about 0.3 s; the bound keeps the n² worst case of the pair tests from
/// starting on the million-triangle scenes the z-buffer is for.
pub const LIMIT: usize = 200_000;

/// Most pair comparisons one frame may make: 15–20 s at the ~20 ns a comparison costs
/// (measured on city views and on 80,000 slats that all overlap in depth and on screen,
/// refused after 17 s), reached only by soups whose polygons nearly all overlap in depth
/// and on screen; such a soup is refused with [`Error::LimitExceeded`] rather than sorted
/// for an hour.
pub const COMPARISON_LIMIT: u64 = 1_000_000_000;

/// Most splits allowed for `n` polygons: every interpenetrating or cyclic pair costs one
/// or two, and the lab's scenes need far fewer than one per polygon; a soup that needs
/// more is refused (quadratically many intersections, or a degenerate cycle).
pub fn split_limit(n: usize) -> usize {
    16 * n + 4096
}

/// A convex polygon of the list: vertices `verts[start..start + len]` (NDC).
#[derive(Debug, Clone, Copy)]
struct Poly {
    start: u32,
    len: u32,
    /// Index of the soup triangle it comes from.
    parent: u32,
    /// The whole (clipped) triangle, drawn from the rasterizer's records; false for pieces.
    whole: bool,
    /// Plane, normal toward the viewer; `None` for zero-area or edge-on polygons.
    plane: Option<DVec4>,
    lo: DVec3,
    hi: DVec3,
    /// Moved to the head of the list once already.
    marked: bool,
}

/// What the comparison of the head with the polygons behind it decided.
enum Step {
    /// Nothing it may obscure: draw it.
    Draw,
    /// Draw this one first.
    Move(u32),
    /// Split polygon `.0` by the plane `.1`.
    Split(u32, DVec4),
}

/// The list being ordered.
struct Sorter {
    verts: Vec<DVec3>,
    polys: Vec<Poly>,
    /// Polygons not moved yet, by farthest depth ascending (the farthest last).
    sorted: Vec<u32>,
    /// Polygons moved to the head, the head last.
    moved: Vec<u32>,
    comparisons: u64,
    reorderings: u64,
    splits: usize,
    unresolved: u64,
    split_limit: usize,
}

impl Sorter {
    /// The list of the soup's triangles the rasterizer would draw (front faces covering a
    /// pixel centre, `screen`), clipped to the frustum, unsorted.
    fn new(soup: &Soup, camera: &Camera, screen: &ScreenTriangles) -> Sorter {
        let mut s = Sorter {
            verts: Vec::new(),
            polys: Vec::new(),
            sorted: Vec::new(),
            moved: Vec::new(),
            comparisons: 0,
            reorderings: 0,
            splits: 0,
            unresolved: 0,
            split_limit: 0,
        };
        let (clip32, clip64) = (scan::clip_from_world(camera), camera.clip_from_world_f64());
        for (k, tri) in soup.triangles().iter().enumerate() {
            if screen.get(k).is_empty() {
                continue;
            }
            let start = s.verts.len();
            if scan::clip_to_ndc(tri, &clip32, &clip64, &mut s.verts) >= 3 {
                let plane = polygon::plane_of(&s.verts[start..]);
                s.add(k as u32, true, plane, start);
            }
        }
        s
    }

    /// Sorts by farthest depth and resolves the order (module doc, steps 2–4), with at most
    /// `split_limit` splits; returns the polygons in drawing order.
    fn order(&mut self, split_limit: usize) -> Result<Vec<u32>> {
        self.split_limit = split_limit;
        let polys = &self.polys;
        self.sorted = (0..polys.len() as u32).collect();
        self.sorted.sort_by(|&i, &j| polys[i as usize].hi.z.total_cmp(&polys[j as usize].hi.z).then(i.cmp(&j)));
        let mut order = Vec::with_capacity(self.polys.len());
        while let Some(p) = self.head() {
            match self.step(p)? {
                Step::Draw => {
                    self.remove(p);
                    order.push(p);
                }
                Step::Move(q) => {
                    self.remove(q);
                    self.polys[q as usize].marked = true;
                    self.moved.push(q);
                    self.reorderings += 1;
                }
                Step::Split(i, plane) => {
                    if !self.split(i, plane)? {
                        // Below the tolerance: nothing left to split, so draw the head as it is.
                        self.unresolved += 1;
                        self.remove(p);
                        order.push(p);
                    }
                }
            }
        }
        Ok(order)
    }

    fn verts(&self, i: u32) -> &[DVec3] {
        let p = &self.polys[i as usize];
        &self.verts[p.start as usize..(p.start + p.len) as usize]
    }

    fn add(&mut self, parent: u32, whole: bool, plane: Option<DVec4>, start: usize) -> u32 {
        let v = &self.verts[start..];
        let (lo, hi) = polygon::extents(v);
        let len = v.len() as u32;
        self.polys.push(Poly { start: start as u32, len, parent, whole, plane, lo, hi, marked: false });
        (self.polys.len() - 1) as u32
    }

    /// Position of `i` in `sorted` (order: farthest depth, then index).
    fn slot(&self, i: u32) -> std::result::Result<usize, usize> {
        let key = |j: u32| (self.polys[j as usize].hi.z, j);
        let k = key(i);
        self.sorted.binary_search_by(|&j| {
            let kj = key(j);
            kj.0.total_cmp(&k.0).then(kj.1.cmp(&k.1))
        })
    }

    fn insert(&mut self, i: u32) {
        if let Err(at) = self.slot(i) {
            self.sorted.insert(at, i);
        }
    }

    fn remove(&mut self, i: u32) {
        if let Some(at) = self.moved.iter().rposition(|&j| j == i) {
            self.moved.remove(at);
        } else if let Ok(at) = self.slot(i) {
            self.sorted.remove(at);
        }
    }

    fn head(&self) -> Option<u32> {
        self.moved.last().or(self.sorted.last()).copied()
    }

    /// Compares the head `p` with every polygon whose depth range overlaps its own.
    fn step(&mut self, p: u32) -> Result<Step> {
        let zmin = self.polys[p as usize].lo.z;
        let moved = self.moved.iter().rev().copied();
        let rest = self.sorted.iter().rev().copied().take_while(|&q| self.polys[q as usize].hi.z > zmin);
        let mut compared = 0;
        let mut step = Step::Draw;
        for q in moved.chain(rest) {
            if q == p || self.polys[q as usize].hi.z <= zmin {
                continue;
            }
            compared += 1;
            if !self.may_obscure(p, q) {
                continue;
            }
            step = self.resolve(p, q);
            break;
        }
        self.comparisons += compared;
        if self.comparisons > COMPARISON_LIMIT {
            return Err(Error::LimitExceeded { method: "painter", what: "pair comparisons", limit: COMPARISON_LIMIT });
        }
        Ok(step)
    }

    /// Tests 1–5: false when one shows that `p` does not obscure `q`.
    fn may_obscure(&self, p: u32, q: u32) -> bool {
        let (a, b) = (&self.polys[p as usize], &self.polys[q as usize]);
        if a.hi.x <= b.lo.x || b.hi.x <= a.lo.x || a.hi.y <= b.lo.y || b.hi.y <= a.lo.y {
            return false;
        }
        let (pv, qv) = (self.verts(p), self.verts(q));
        // Coplanar polygons overlap exactly where they overlap on screen; there the z-buffer
        // keeps the smaller triangle ID (in-order drawing), so the smaller one must be
        // drawn last: P, drawn now, may obscure a coplanar Q only when P's ID is smaller.
        let tie_keeps_p = a.parent < b.parent;
        let coplanar = |(lo, hi): (f64, f64)| lo >= -EPS && hi <= EPS;
        if b.plane.is_some_and(|pl| {
            let r = polygon::reach(pl, pv);
            r.1 <= EPS && !(tie_keeps_p && coplanar(r))
        }) {
            return false; // (3) P behind Q's plane
        }
        if a.plane.is_some_and(|pl| {
            let r = polygon::reach(pl, qv);
            r.0 >= -EPS && !(tie_keeps_p && coplanar(r))
        }) {
            return false; // (4) Q in front of P's plane
        }
        polygon::overlap_2d(pv, qv) // (5)
    }

    /// `p` may obscure `q`: move `q` ahead of it, or split.
    fn resolve(&self, p: u32, q: u32) -> Step {
        let (a, b) = (&self.polys[p as usize], &self.polys[q as usize]);
        let (pv, qv) = (self.verts(p), self.verts(q));
        let q_behind = a.plane.is_some_and(|pl| polygon::reach(pl, qv).1 <= EPS); // (3′)
        let p_in_front = b.plane.is_some_and(|pl| polygon::reach(pl, pv).0 >= -EPS); // (4′)
        if !b.marked && (q_behind || p_in_front) {
            return Step::Move(q);
        }
        if polygon::spans(a.plane, qv) {
            return Step::Split(q, a.plane.unwrap_or_default());
        }
        if polygon::spans(b.plane, pv) {
            return Step::Split(p, b.plane.unwrap_or_default());
        }
        // A cycle with no crossing plane: halve the larger on screen across its long side.
        let size = |x: &Poly| (x.hi - x.lo).truncate().max_element();
        let (i, x) = if size(a) >= size(b) { (p, a) } else { (q, b) };
        let (e, c) = (x.hi - x.lo, (x.hi + x.lo) * 0.5);
        let cut = if e.x >= e.y { DVec4::new(1.0, 0.0, 0.0, -c.x) } else { DVec4::new(0.0, 1.0, 0.0, -c.y) };
        Step::Split(i, cut)
    }

    /// Splits polygon `i` by `plane`; false when it does not cross it (nothing to split).
    fn split(&mut self, i: u32, plane: DVec4) -> Result<bool> {
        if !polygon::spans(Some(plane), self.verts(i)) {
            return Ok(false);
        }
        if self.splits >= self.split_limit {
            return Err(Error::LimitExceeded {
                method: "painter",
                what: "polygon splits",
                limit: self.split_limit as u64,
            });
        }
        self.splits += 1;
        self.remove(i);
        let x = self.polys[i as usize];
        let (mut front, mut back) = (Vec::new(), Vec::new());
        polygon::split(self.verts(i), plane, &mut front, &mut back);
        for piece in [front, back] {
            if piece.len() >= 3 {
                let start = self.verts.len();
                self.verts.extend_from_slice(&piece);
                let j = self.add(x.parent, false, x.plane, start);
                self.insert(j);
            }
        }
        Ok(true)
    }
}

/// The painter's algorithm with the Newell–Newell–Sancha tests (see the module doc): writes
/// `fb.ids` and `fb.depth`. Counters: `comparisons` (pairs tested), `reorderings`
/// (polygons moved ahead), `splits`, `unresolved` (pairs that could not be split: below
/// the plane tolerance, drawn as they were), `polygons_drawn`, `fragments_written`.
///
/// Fails with [`Error::TooLarge`] above [`LIMIT`] triangles, and with
/// [`Error::LimitExceeded`] when the order needs more than [`split_limit`] splits or
/// [`COMPARISON_LIMIT`] pair comparisons.
pub fn render(soup: &Soup, camera: &Camera, fb: &mut Framebuffer) -> Result<Counters> {
    soup.check_size("painter", LIMIT)?;
    let screen = ScreenTriangles::new(soup.triangles(), camera, fb.width(), fb.height(), CULL_BACK_FACES)?;
    let mut s = Sorter::new(soup, camera, &screen);
    let order = s.order(split_limit(s.polys.len()))?;
    scan::clear_visibility(fb);
    let vp = Viewport::new(fb.width(), fb.height(), true);
    let mut pieces = Vec::new();
    let mut written = 0;
    for &i in &order {
        let x = s.polys[i as usize];
        let id = Soup::id(x.parent as usize);
        if x.whole {
            for t in screen.get(x.parent as usize) {
                written += scan::overwrite(t, id, fb);
            }
        } else {
            pieces.clear();
            scan::setup_ndc_polygon(&vp, s.verts(i), id, &mut pieces);
            for t in &pieces {
                written += scan::overwrite(t, id, fb);
            }
        }
    }
    let mut counters = Counters::new();
    counters.add("comparisons", s.comparisons);
    counters.add("reorderings", s.reorderings);
    counters.add("splits", s.splits as u64);
    counters.add("unresolved", s.unresolved);
    counters.add("polygons_drawn", order.len() as u64);
    counters.add("fragments_written", written);
    Ok(counters)
}

/// The plain depth sort the Newell–Newell–Sancha tests correct: front-facing triangles
/// drawn whole, farthest view-space centroid first, no tests and no splits; wrong wherever
/// a triangle nearer by centroid lies behind another somewhere (long triangles,
/// interpenetration, cycles). Writes `fb.ids` and `fb.depth`. Counters: `triangles_sorted`,
/// `fragments_written`. Linear-logarithmic, so it takes any soup.
pub fn render_centroid_sort(soup: &Soup, camera: &Camera, fb: &mut Framebuffer) -> Result<Counters> {
    let screen = ScreenTriangles::new(soup.triangles(), camera, fb.width(), fb.height(), CULL_BACK_FACES)?;
    let view = camera.view.view_from_world_f64();
    let mut keyed: Vec<(f64, u32)> = (0..screen.len())
        .filter(|&k| !screen.get(k).is_empty())
        .map(|k| {
            let t = soup.triangles()[k];
            let c = (t[0].as_dvec3() + t[1].as_dvec3() + t[2].as_dvec3()) / 3.0;
            // View space looks down −z: the most negative z is the farthest.
            (view.transform_point3(c).z, k as u32)
        })
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    scan::clear_visibility(fb);
    let mut written = 0;
    for &(_, k) in &keyed {
        for t in screen.get(k as usize) {
            written += scan::overwrite(t, Soup::id(k as usize), fb);
        }
    }
    let mut c = Counters::new();
    c.add("triangles_sorted", keyed.len() as u64);
    c.add("fragments_written", written);
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use sightline_scene::{Angle, LookAt};

    /// Two triangles piercing each other need a split; with none allowed the sort fails,
    /// naming the method and the limit.
    #[test]
    fn running_out_of_splits_is_an_error_naming_the_limit() {
        let soup = Soup::from_triangles(vec![
            [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.2, 0.0)],
            [Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.2, 1.0), Vec3::new(0.0, 0.9, 1.0)],
        ]);
        let look = LookAt { eye: Vec3::new(0.2, 0.3, 5.0), fovy: Angle::degrees(50.0), ..LookAt::default() };
        let cam = Camera::perspective(&look, 1.0).unwrap();
        let screen = ScreenTriangles::new(soup.triangles(), &cam, 32, 32, CULL_BACK_FACES).unwrap();
        let mut s = Sorter::new(&soup, &cam, &screen);
        let err = s.order(0).unwrap_err().to_string();
        assert!(err.contains("painter") && err.contains("more than 0 polygon splits"), "{err}");
        let mut s = Sorter::new(&soup, &cam, &screen);
        let order = s.order(split_limit(2)).unwrap();
        assert!(s.splits >= 1 && order.len() >= 3, "{} splits, {} polygons", s.splits, order.len());
    }
}

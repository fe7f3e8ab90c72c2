//! Warnock's area subdivision: decide what a window of the screen shows if that is simple,
//! else split it in four and ask again.
//!
//! John Warnock's thesis ("A Hidden-Surface Algorithm for Computer Generated Half-Tone
//! Pictures", University of Utah, 1969) works in image space and divides and conquers: a
//! window of the screen is *simple* when
//! 1. no polygon reaches into it (it shows the background),
//! 2. one polygon reaches into it (draw that polygon, background around it), or
//! 3. one polygon *surrounds* it and lies in front of every other polygon reaching into it
//!    (the window shows that polygon only);
//!
//! otherwise it is split in four and each quarter is looked at in turn, down to single
//! pixels, where the polygon nearest at the pixel decides. Each polygon's relation to a
//! window is one of four — surrounding (covers the whole window), intersecting (crosses its
//! border), contained (lies inside it) or disjoint — and a quarter only looks at the
//! polygons that were not disjoint from its parent: the list shrinks on the way down, which
//! is where the method gets its speed. Foley, van Dam, Feiner & Hughes, *Computer Graphics:
//! Principles and Practice* (2nd ed., 1990), §15.7.1 "Area-subdivision algorithms", gives
//! the algorithm in this form, with its four relations.
//!
//! # Decided at pixel centres, like the rasterizer
//!
//! The polygons are the soup's triangles exactly as the engine's rasterizer sets them up:
//! transformed by the camera, clipped in homogeneous space where they cross the near or far
//! plane or the guard band ([`crate::clip`], Sutherland–Hodgman; the pieces of a clipped
//! triangle are a fan of triangles with its ID), projected, snapped to 1/256 pixel and
//! oriented (back faces dropped when culling is on). A window is a rectangle of *pixel
//! centres*, and every relation is decided on those centres with the same fixed-point edge
//! functions and fill rule as the rasterizer (left and bottom edges own the centres exactly
//! on them): a polygon is disjoint when one edge function is negative at every centre of
//! the window, surrounding when all three are non-negative at every centre (the functions
//! are affine, so the window's corners decide both). "In front" compares bounds of the
//! depth planes over the window, widened by the rounding a per-pixel evaluation can add,
//! and must hold strictly; at a single pixel, the depth the rasterizer would compute decides,
//! with exact ties going to the smaller triangle ID, as in the z-buffer. So the IDs are the
//! rasterizer's, pixel for pixel, on the same triangles.
//!
//! # Cost and the size limit
//!
//! The windows form a quadtree over the screen, walked depth first with an explicit stack.
//! The lists of the windows on the current path live in one arena (a parent's list stays
//! below its children's until its last child is done), so memory is at most one list per
//! level: 14 × n polygon indices at 8192 pixels a side. Time is the number of
//! window–polygon tests: a polygon is tested in every window it reaches into, and along
//! silhouette edges the subdivision goes down to single pixels, so the cost grows with the
//! triangle count times the length of the edges visible on screen — and, in the worst case
//! (many polygons overlapping at equal depths), with pixels × triangles. [`MAX_TRIANGLES`]
//! caps the input at 2^17 = 131,072 triangles: enough for the lab's scaling family up to
//! `city:100000` (102,570 triangles), and a bound on the worst case, so a million-triangle
//! scene is refused with [`Error::TooLarge`](crate::Error::TooLarge) instead of running for
//! minutes.

use glam::Affine3A;
use sightline_scene::Camera;

use super::{Counters, Soup};
use crate::depth::DepthFormat;
use crate::edge::{edges, Edge, Tri};
use crate::geometry::{Chunk, Item, Piece, Source};
use crate::setup::Viewport;
use crate::{Framebuffer, Result};

/// The method's name, as the lab and its errors spell it.
pub const NAME: &str = "warnock";

/// The most triangles [`render`] takes (see the module docs: the bound on the worst case).
pub const MAX_TRIANGLES: usize = 1 << 17;

/// Levels of the window quadtree: the whole screen is level 0 and a side of at most
/// [`crate::MAX_SIZE`] = 2^13 pixels halves down to one pixel in 13 steps.
const LEVELS: usize = 14;

/// The counter of windows visited at each level of the quadtree.
const LEVEL_NAMES: [&str; LEVELS] = [
    "windows_level_0",
    "windows_level_1",
    "windows_level_2",
    "windows_level_3",
    "windows_level_4",
    "windows_level_5",
    "windows_level_6",
    "windows_level_7",
    "windows_level_8",
    "windows_level_9",
    "windows_level_10",
    "windows_level_11",
    "windows_level_12",
    "windows_level_13",
];

/// How [`render_with`] draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Options {
    /// Drop back faces first, as the rasterizer does with the same option (on by default,
    /// as in [`crate::RenderOptions`]).
    pub backface_culling: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options { backface_culling: true }
    }
}

/// Draws `soup` seen by `camera` into `fb` by area subdivision, with back faces culled as
/// the engine does by default: writes `fb.ids` and `fb.depth` (every pixel), not the colour
/// (see [`crate::shade_pass`]).
///
/// Counters: `triangles`, `clipped` and `backface_culled` (the geometry stage), `polygons`
/// (set-up triangles after clipping and culling), `windows` and
/// `windows_level_k` (windows visited, in all and per level of the quadtree, level 0 being the
/// whole screen), `polygons_tested` (window–polygon relation tests) and how many came out
/// `surrounding`, `intersecting`, `contained` and `disjoint`, and how each window was decided:
/// `empty_windows`, `single_polygon_windows`, `surrounded_windows`, `pixel_windows`
/// (single pixels decided by depth).
///
/// Fails with [`Error::TooLarge`](crate::Error::TooLarge) above [`MAX_TRIANGLES`], and with
/// [`Error::DepthRange`](crate::Error::DepthRange) for a projection whose depths `f32`
/// cannot tell apart (as the rasterizer does).
pub fn render(soup: &Soup, camera: &Camera, fb: &mut Framebuffer) -> Result<Counters> {
    render_with(soup, camera, fb, &Options::default())
}

/// [`render`] with options.
pub fn render_with(soup: &Soup, camera: &Camera, fb: &mut Framebuffer, opts: &Options) -> Result<Counters> {
    soup.check_size(NAME, MAX_TRIANGLES)?;
    DepthFormat::F32.check_resolves(&camera.projection)?;
    let mut counters = Counters::new();
    let polys = polygons(soup, camera, fb.width(), fb.height(), opts.backface_culling, &mut counters);
    fb.ids.fill(0);
    fb.depth.fill(1.0);
    let mut sub = Subdivision { polys: &polys, fb, tally: Tally::default(), arena: Vec::new(), stack: Vec::new() };
    sub.run();
    sub.tally.report(&mut counters);
    Ok(counters)
}

/// A polygon as the subdivision tests it: the set-up triangle (depth plane, ID), its edge
/// functions with the fill rule's bias, and its pixel-centre bounding box on the screen.
#[derive(Clone, Copy)]
struct Poly {
    tri: Tri,
    edges: [Edge; 3],
    bbox: [i32; 4],
}

impl Poly {
    /// True when the centre of pixel (px, py) is inside (fill rule included).
    #[inline]
    fn covers(&self, px: i32, py: i32) -> bool {
        let (px, py) = (px as i64, py as i64);
        self.edges.iter().all(|e| e.a * px + e.b * py + e.c >= 0)
    }

    /// The depth key the rasterizer computes at pixel (px, py) (`f32` depth).
    #[inline]
    fn key_at(&self, px: i32, py: i32) -> u32 {
        DepthFormat::F32.key(self.tri.depth_at(self.tri.depth_row(py), px))
    }

    /// Keys bounding the depth plane over the pixel centres of `rect`.
    #[inline]
    fn key_bounds(&self, rect: [i32; 4]) -> (u32, u32) {
        let (lo, hi) = self.tri.plane_bounds(rect);
        (DepthFormat::F32.key(lo), DepthFormat::F32.key(hi))
    }
}

/// The soup's triangles set up for `camera` on a `width × height` target, by the
/// rasterizer's own geometry stage (transform, outcodes, homogeneous clipping, snapping,
/// orientation, culling), in ID order.
fn polygons(soup: &Soup, camera: &Camera, width: u32, height: u32, cull: bool, counters: &mut Counters) -> Vec<Poly> {
    let positions = soup.triangles().as_flattened();
    let indices: Vec<u32> = (0..positions.len() as u32).collect();
    let n = soup.len() as u32; // at most MAX_TRIANGLES
    let clip_from_local = camera.clip_from_local(&Affine3A::IDENTITY);
    let item = Item {
        src: Source::Mesh { positions, indices: &indices, clip_from_local, ids: None },
        first_id: 1,
        source_triangles: n,
    };
    let mut chunk = Chunk::default();
    chunk.process(&[item][..], &[Piece { item: 0, start: 0, count: n }], &Viewport::new(width, height, true), cull);
    let st = &chunk.stats;
    counters.add("triangles", st.triangles_in);
    counters.add("clipped", st.clipped);
    counters.add("backface_culled", st.backface_culled);
    counters.add("polygons", chunk.tris.len() as u64);
    chunk.tris.iter().map(|t| Poly { tri: *t, edges: edges(t), bbox: t.bbox.map(i32::from) }).collect()
}

/// A polygon's relation to a window (Foley et al. §15.7.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Relation {
    /// Covers every pixel centre of the window.
    Surrounding,
    /// Reaches into the window and out of it.
    Intersecting,
    /// Lies inside the window (its bounding box does).
    Contained,
    /// Covers no pixel centre of the window (known from its box or one edge function).
    Disjoint,
}

/// The relation of `p` to the window of pixel centres `[x0, y0, x1, y1]` (inclusive). Edge
/// functions are affine, so their extremes over the window are at its corners.
#[inline]
fn relation(p: &Poly, [x0, y0, x1, y1]: [i32; 4]) -> Relation {
    let b = p.bbox;
    if b[0] > x1 || b[2] < x0 || b[1] > y1 || b[3] < y0 {
        return Relation::Disjoint;
    }
    let (w, h) = ((x1 - x0) as i64, (y1 - y0) as i64);
    let mut inside_all = true;
    for e in &p.edges {
        let v = e.a * x0 as i64 + e.b * y0 as i64 + e.c;
        if v + e.a.max(0) * w + e.b.max(0) * h < 0 {
            return Relation::Disjoint;
        }
        inside_all &= v + e.a.min(0) * w + e.b.min(0) * h >= 0;
    }
    if inside_all {
        Relation::Surrounding
    } else if b[0] >= x0 && b[2] <= x1 && b[1] >= y0 && b[3] <= y1 {
        Relation::Contained
    } else {
        Relation::Intersecting
    }
}

/// A window waiting on the stack: its pixel-centre rectangle, its level, and where its
/// parent's polygon list lies in the arena.
#[derive(Debug, Clone, Copy)]
struct Window {
    rect: [i32; 4],
    level: u8,
    list: (u32, u32),
}

/// What the subdivision did.
#[derive(Debug, Default)]
struct Tally {
    levels: [u64; LEVELS],
    relations: [u64; 4],
    empty: u64,
    single: u64,
    surrounded: u64,
    pixels: u64,
}

impl Tally {
    fn report(&self, c: &mut Counters) {
        c.add("windows", self.levels.iter().sum());
        for (name, &n) in LEVEL_NAMES.iter().zip(&self.levels) {
            if n > 0 {
                c.add(name, n);
            }
        }
        c.add("polygons_tested", self.relations.iter().sum());
        for (name, &n) in ["surrounding", "intersecting", "contained", "disjoint"].iter().zip(&self.relations) {
            c.add(name, n);
        }
        c.add("empty_windows", self.empty);
        c.add("single_polygon_windows", self.single);
        c.add("surrounded_windows", self.surrounded);
        c.add("pixel_windows", self.pixels);
    }
}

/// The depth key of the cleared buffer: a fragment must be below it to be drawn.
const BACKGROUND_KEY: u32 = 0x3f80_0000; // 1.0f32

/// The subdivision's state: the polygons, the target, the window stack and the list arena.
struct Subdivision<'a> {
    polys: &'a [Poly],
    fb: &'a mut Framebuffer,
    tally: Tally,
    /// Polygon indices: the lists of the windows on the current path, each above its parent's.
    arena: Vec<u32>,
    stack: Vec<Window>,
}

impl Subdivision<'_> {
    fn run(&mut self) {
        debug_assert_eq!(DepthFormat::F32.key(1.0), BACKGROUND_KEY);
        let n = self.polys.len() as u32;
        self.arena.extend(0..n);
        let (w, h) = (self.fb.width() as i32, self.fb.height() as i32);
        self.stack.push(Window { rect: [0, 0, w - 1, h - 1], level: 0, list: (0, n) });
        while let Some(win) = self.stack.pop() {
            self.visit(win);
        }
    }

    /// Filters the parent's list down to this window's, then decides the window or splits it.
    fn visit(&mut self, win: Window) {
        let rect = win.rect;
        self.tally.levels[(win.level as usize).min(LEVELS - 1)] += 1;
        // Everything above the parent's list belongs to finished siblings.
        self.arena.truncate(win.list.1 as usize);
        let start = self.arena.len();
        // The surrounding polygon with the nearest far bound, the candidate for case 3.
        let mut front: Option<(u32, u32)> = None;
        for k in win.list.0 as usize..win.list.1 as usize {
            let i = self.arena[k];
            let p = &self.polys[i as usize];
            let rel = relation(p, rect);
            self.tally.relations[rel as usize] += 1;
            match rel {
                Relation::Disjoint => continue,
                Relation::Surrounding => {
                    let far = p.key_bounds(rect).1;
                    // Equal bounds: the smaller ID, as depth ties go (the list is in ID order).
                    if front.is_none_or(|(_, f)| far < f) {
                        front = Some((i, far));
                    }
                }
                Relation::Intersecting | Relation::Contained => {}
            }
            self.arena.push(i);
        }
        let list = start..self.arena.len();
        match list.len() {
            0 => self.tally.empty += 1, // the background, already there
            1 => {
                self.tally.single += 1;
                self.paint(self.arena[start], rect);
            }
            _ => {
                if let Some((s, _)) = front.filter(|&(s, far)| self.in_front(s, far, rect, list.clone())) {
                    self.tally.surrounded += 1;
                    self.paint(s, rect);
                } else if rect[0] == rect[2] && rect[1] == rect[3] {
                    self.tally.pixels += 1;
                    self.decide_pixel(rect[0], rect[1], list);
                } else {
                    self.split(win, (start as u32, self.arena.len() as u32));
                }
            }
        }
    }

    /// True when polygon `s`, whose depth over `rect` is at most the key `far`, lies
    /// strictly in front of every other polygon of the window's list over the whole window.
    fn in_front(&self, s: u32, far: u32, rect: [i32; 4], list: std::ops::Range<usize>) -> bool {
        self.arena[list].iter().all(|&i| i == s || far < self.polys[i as usize].key_bounds(rect).0)
    }

    /// Draws polygon `i` over the pixel centres of `rect` it covers (over the background:
    /// the window holds no other polygon, or `i` is in front of them all).
    fn paint(&mut self, i: u32, rect: [i32; 4]) {
        let p = &self.polys[i as usize];
        let (x0, y0) = (rect[0].max(p.bbox[0]), rect[1].max(p.bbox[1]));
        let (x1, y1) = (rect[2].min(p.bbox[2]), rect[3].min(p.bbox[3]));
        let w = self.fb.width() as usize;
        for py in y0..=y1 {
            let zrow = p.tri.depth_row(py);
            for px in x0..=x1 {
                if !p.covers(px, py) {
                    continue;
                }
                let key = DepthFormat::F32.key(p.tri.depth_at(zrow, px));
                if key < BACKGROUND_KEY {
                    let at = py as usize * w + px as usize;
                    self.fb.ids[at] = p.tri.id;
                    self.fb.depth[at] = DepthFormat::F32.depth(key);
                }
            }
        }
    }

    /// A single pixel: the nearest of the polygons covering its centre, exact depth ties to
    /// the smaller ID, the background when none is nearer than the far plane.
    fn decide_pixel(&mut self, px: i32, py: i32, list: std::ops::Range<usize>) {
        let (mut key, mut id) = (BACKGROUND_KEY, 0u32);
        for &i in &self.arena[list] {
            let p = &self.polys[i as usize];
            if !p.covers(px, py) {
                continue;
            }
            let k = p.key_at(px, py);
            if k < key || (k == key && p.tri.id < id) {
                (key, id) = (k, p.tri.id);
            }
        }
        if id != 0 {
            let at = py as usize * self.fb.width() as usize + px as usize;
            self.fb.ids[at] = id;
            self.fb.depth[at] = DepthFormat::F32.depth(key);
        }
    }

    /// Pushes the (up to) four quarters of `win`, whose own list is `list`; the top-left
    /// quarter is visited first.
    fn split(&mut self, win: Window, list: (u32, u32)) {
        let [x0, y0, x1, y1] = win.rect;
        let (xm, ym) = ((x0 + x1) / 2, (y0 + y1) / 2);
        let xs: &[(i32, i32)] = if x0 < x1 { &[(xm + 1, x1), (x0, xm)] } else { &[(x0, x1)] };
        let ys: &[(i32, i32)] = if y0 < y1 { &[(ym + 1, y1), (y0, ym)] } else { &[(y0, y1)] };
        for &(ya, yb) in ys {
            for &(xa, xb) in xs {
                self.stack.push(Window { rect: [xa, ya, xb, yb], level: win.level + 1, list });
            }
        }
    }
}

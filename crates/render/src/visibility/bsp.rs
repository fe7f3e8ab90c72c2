//! Rendering through a BSP tree: the autopartition of `sightline-spatial` walked from the
//! eye, back to front without a depth buffer, or front to back with a coverage mask.
//!
//! Fuchs, Kedem & Naylor, "On Visible Surface Generation by A Priori Tree Structures"
//! (SIGGRAPH 1980); Foley, van Dam, Feiner & Hughes, *Computer Graphics: Principles and
//! Practice* (2nd ed., 1990), §15.5.2. Each node of the tree holds the triangles lying in
//! one plane; everything in front of the plane is in one subtree, everything behind in the
//! other (triangles crossing it were split when the tree was built, once for every view).
//! Nothing on the eye's side of a plane can be hidden by anything on the other side, so for
//! any eye:
//!
//! * **back to front**: far subtree, the node's triangles, near subtree, each drawn over what
//!   is there — the painter's algorithm with an order that is right by construction, no
//!   depth buffer, no comparisons at draw time;
//! * **front to back**: near subtree, node, far subtree, with a per-pixel coverage mask: a
//!   pixel is written by the first triangle that covers it and never again, and the walk
//!   stops as soon as every pixel is covered (the ID plane is the mask: 0 = not yet
//!   covered). Each pixel is written once, which the back-to-front walk's overdraw is not.
//!
//! The eye is the camera's centre of projection as a homogeneous point, so parallel
//! projections (an eye at infinity) order the tree correctly too ([`viewpoint`]).
//! Pieces of split triangles keep their source triangle's ID; whole triangles are drawn from
//! the rasterizer's own set-up records and pieces through the same setup
//! (the lab's `scan` module), pieces of a back-facing or invisible triangle not at all.

use std::ops::ControlFlow;

use glam::{DVec3, DVec4, Vec3, Vec4};
use sightline_scene::Camera;
use sightline_spatial::{BspOrder, BspParams, BspStats, BspTree};

use super::scan::{self, ScreenTriangles, CULL_BACK_FACES};
use super::{Counters, Soup};
use crate::{Framebuffer, Result};

/// Most triangles the BSP renderer builds a tree over: the autopartition's splits can grow
/// the tree faster than the input (up to quadratically for a soup of long crossing
/// triangles), and the tree is built on one core.
pub const LIMIT: usize = 2_000_000;

/// Which walk draws the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BspMode {
    /// Far to near, each triangle over the last, no depth buffer.
    BackToFront,
    /// Near to far, each pixel written once, stopping when the screen is covered.
    FrontToBack,
}

/// Not a piece: the stored triangle is its source triangle, whole.
const WHOLE: u32 = u32::MAX;

/// A BSP tree over a soup, built once and drawn from any camera.
#[derive(Debug, Clone)]
pub struct BspRenderer {
    tree: BspTree,
    triangles: Vec<[Vec3; 3]>,
    /// Per stored triangle: [`WHOLE`], or its index in `pieces`.
    piece_of: Vec<u32>,
    pieces: Vec<[Vec3; 3]>,
}

impl BspRenderer {
    /// Builds the tree over `soup` (the default autopartition parameters). Fails with
    /// [`crate::Error::TooLarge`] above [`LIMIT`] triangles.
    pub fn new(soup: &Soup) -> Result<BspRenderer> {
        soup.check_size("bsp", LIMIT)?;
        let tree = BspTree::build(soup.triangles(), &BspParams::default());
        let mut pieces = Vec::new();
        let piece_of = tree
            .triangles()
            .iter()
            .map(|t| {
                if t.v == soup.triangles()[t.source as usize] {
                    WHOLE
                } else {
                    pieces.push(t.v);
                    (pieces.len() - 1) as u32
                }
            })
            .collect();
        Ok(BspRenderer { tree, triangles: soup.triangles().to_vec(), piece_of, pieces })
    }

    /// The tree's construction counters (nodes, depth, splits, triangles stored).
    pub fn stats(&self) -> BspStats {
        self.tree.stats()
    }

    /// Draws the view from `camera` into `fb.ids` and `fb.depth` by the walk `mode`.
    /// Counters: `nodes_visited`, `triangles_drawn`, `fragments_tested` (covered centres
    /// met), `fragments_written`, `split_triangles` (splits made when the tree was built),
    /// `stored_triangles`.
    pub fn render(&self, camera: &Camera, fb: &mut Framebuffer, mode: BspMode) -> Result<Counters> {
        let (w, h) = (fb.width(), fb.height());
        let whole = ScreenTriangles::new(&self.triangles, camera, w, h, CULL_BACK_FACES)?;
        // Pieces are drawn whatever their own facing: their source's facing decides.
        let pieces = ScreenTriangles::new(&self.pieces, camera, w, h, false)?;
        scan::clear_visibility(fb);
        let stored = self.tree.triangles();
        let (mut drawn, mut tested, mut written) = (0u64, 0u64, 0u64);
        let pixels = fb.len() as u64;
        let order = match mode {
            BspMode::BackToFront => BspOrder::BackToFront,
            BspMode::FrontToBack => BspOrder::FrontToBack,
        };
        let visited = self.tree.visit(viewpoint(camera), order, |range| {
            // A node's triangles are coplanar and listed by source (`BspTree` lists them so);
            // where copies tie, the z-buffer keeps the smaller ID, so the smaller is drawn
            // last when overwriting and first when each pixel is written once.
            let back_to_front = mode == BspMode::BackToFront;
            let mut range = range;
            while let Some(i) = if back_to_front { range.next_back() } else { range.next() } {
                let t = &stored[i as usize];
                let source = t.source as usize;
                if whole.get(source).is_empty() {
                    continue; // back-facing, too small or outside: so are its pieces
                }
                let records = match self.piece_of[i as usize] {
                    WHOLE => whole.get(source),
                    p => pieces.get(p as usize),
                };
                drawn += 1;
                let id = Soup::id(source);
                for r in records {
                    match mode {
                        BspMode::BackToFront => {
                            let n = scan::overwrite(r, id, fb);
                            tested += n;
                            written += n;
                        }
                        BspMode::FrontToBack => {
                            let (ids, depth) = (&mut fb.ids, &mut fb.depth);
                            scan::for_each_fragment(r, w, |k, z| {
                                tested += 1;
                                if ids[k] == 0 {
                                    ids[k] = id;
                                    depth[k] = z;
                                    written += 1;
                                }
                            });
                        }
                    }
                }
            }
            if mode == BspMode::FrontToBack && written == pixels {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        });
        let mut c = Counters::new();
        c.add("nodes_visited", visited as u64);
        c.add("triangles_drawn", drawn);
        c.add("fragments_tested", tested);
        c.add("fragments_written", written);
        c.add("split_triangles", self.tree.stats().splits as u64);
        c.add("stored_triangles", stored.len() as u64);
        Ok(c)
    }
}

/// [`BspRenderer::new`] then [`BspRenderer::render`]: build and draw one view.
pub fn render(soup: &Soup, camera: &Camera, fb: &mut Framebuffer, mode: BspMode) -> Result<Counters> {
    BspRenderer::new(soup)?.render(camera, fb, mode)
}

/// The camera's centre of projection as a homogeneous world point: `(eye, 1)` for a
/// perspective camera; for a parallel (orthographic or oblique) projection, `(d, 0)` with
/// `d` the unit direction from the scene toward the viewer. It is the point every
/// projector passes through: the one clip-space `x`, `y` and `w` all vanish at, found as
/// the 4D cross product of those three rows of `clip_from_world` (in f64).
pub fn viewpoint(camera: &Camera) -> Vec4 {
    let m = camera.clip_from_world_f64();
    let (a, b, c) = (m.row(0), m.row(1), m.row(3));
    let det = |p: DVec3, q: DVec3, r: DVec3| p.dot(q.cross(r));
    let pick = |v: DVec4, skip: usize| {
        let e = v.to_array();
        let k: Vec<f64> = (0..4).filter(|&i| i != skip).map(|i| e[i]).collect();
        DVec3::new(k[0], k[1], k[2])
    };
    let minor = |skip: usize| det(pick(a, skip), pick(b, skip), pick(c, skip));
    let e = DVec4::new(minor(0), -minor(1), minor(2), -minor(3));
    let scale = e.truncate().length();
    if e.w.abs() > 1e-9 * scale {
        return (e.truncate() / e.w).as_vec3().extend(1.0);
    }
    // At infinity: point the direction to where clip z (depth) decreases, the viewer's side.
    let d = if m.row(2).dot(e) < 0.0 { e } else { -e };
    (d.truncate() / scale).as_vec3().extend(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sightline_scene::{Angle, LookAt, Projection, View};

    #[test]
    fn the_viewpoint_is_the_eye_or_the_direction_toward_the_viewer() {
        let look = LookAt {
            eye: Vec3::new(3.0, 2.0, -5.0),
            target: Vec3::new(0.5, 0.0, 1.0),
            fovy: Angle::degrees(50.0),
            ..LookAt::default()
        };
        let cam = Camera::perspective(&look, 1.5).unwrap();
        let v = viewpoint(&cam);
        assert_eq!(v.w, 1.0);
        assert!((v.truncate() - look.eye).length() < 1e-4, "{v}");
        let view = View::look_at(look.eye, look.target, Vec3::Y).unwrap();
        let ortho = Camera::new(view, Projection::orthographic(-2.0, 2.0, -1.0, 1.0, 0.1, 50.0).unwrap()).unwrap();
        let v = viewpoint(&ortho);
        assert_eq!(v.w, 0.0);
        let toward_viewer = (look.eye - look.target).normalize();
        assert!((v.truncate() - toward_viewer).length() < 1e-5, "{v} vs {toward_viewer}");
    }
}

//! Wireframe: Cohen–Sutherland line clipping to the viewport and Bresenham lines.
//!
//! * Bresenham, "Algorithm for computer control of a digital plotter" (IBM Systems
//!   Journal, 1965): integer-only, one error update per pixel, all octants.
//! * Cohen–Sutherland (Newman & Sproull 1979): 4-bit region codes, trivial accept/reject,
//!   otherwise move an outside end point to the crossed border and repeat.
//!
//! Triangle edges are first clipped against the near plane in clip space (a segment with an
//! end behind the eye has no sensible projection), then projected, clipped in 2D to the
//! pixel-center rectangle, rounded to pixel centers and drawn. Lines are not depth-tested,
//! except in hidden-line mode.
//!
//! # Hidden lines
//!
//! [`Wireframe::HiddenLine`] draws the edges over the filled frame and keeps a line pixel
//! only where the edge is the visible surface there: the pixel shows the edge's own
//! triangle, or the edge's window depth (linear along the projected segment, as window
//! depth is on any projected line) is not farther than the depth buffer's by more than a
//! tolerance: the image-space form of hidden-line removal by a depth buffer (Foley, van
//! Dam, Feiner & Hughes, *Computer Graphics: Principles and Practice*, 2nd ed., 1990,
//! §15.3 and §15.4). The tolerance is what `glPolygonOffset(1, 4)` would add:
//!
//! * slope-scaled: a Bresenham pixel centre lies up to half a pixel off the edge across the
//!   line (along its minor axis), where the neighbour triangle sharing the edge may already
//!   be nearer than the edge by half a pixel's depth change. That change is measured in the
//!   depth buffer itself, between the pixel and its neighbours across the line that show the
//!   same triangle, so grazing surfaces get the larger tolerance they need and surfaces
//!   facing the viewer almost none;
//! * constant: 4 units in the last place of the stored depth, for the rounding of the
//!   rasterizer's f32 depth plane against the line's f64 interpolation.
//!
//! An occluder nearer than that hides the edge: edges behind a surface more than a pixel's
//! depth change in front of them disappear.

use glam::{DVec2, DVec3, Vec4};
use sightline_scene::{Camera, Instance, Scene};

use crate::options::{DrawItem, RenderOptions, Wireframe};
use crate::{Error, Framebuffer, Result};

/// Calls `plot` for each pixel of the Bresenham line from (x0, y0) to (x1, y1), ends
/// included.
pub fn bresenham(x0: i32, y0: i32, x1: i32, y1: i32, mut plot: impl FnMut(i32, i32)) {
    let (dx, dy) = ((x1 as i64 - x0 as i64).abs(), -(y1 as i64 - y0 as i64).abs());
    let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
    let mut err = dx + dy;
    let (mut x, mut y) = (x0, y0);
    loop {
        plot(x, y);
        if x == x1 && y == y1 {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x += sx;
        }
        if e2 <= dx {
            err += dx;
            y += sy;
        }
    }
}

const L: u8 = 1;
const R: u8 = 2;
const B: u8 = 4;
const T: u8 = 8;

fn region(p: DVec2, max: DVec2) -> u8 {
    let mut c = 0;
    if p.x < 0.0 {
        c |= L;
    } else if p.x > max.x {
        c |= R;
    }
    if p.y < 0.0 {
        c |= T;
    } else if p.y > max.y {
        c |= B;
    }
    c
}

/// Cohen–Sutherland: clips the segment to `[0, max.x] × [0, max.y]`; `None` when nothing
/// is left (or an end is not finite).
pub fn clip_segment(mut a: DVec2, mut b: DVec2, max: DVec2) -> Option<(DVec2, DVec2)> {
    if !(a.is_finite() && b.is_finite()) {
        return None;
    }
    let (mut ca, mut cb) = (region(a, max), region(b, max));
    // Each round moves one end onto a border: at most four rounds per end.
    for _ in 0..8 {
        if ca | cb == 0 {
            return Some((a, b));
        }
        if ca & cb != 0 {
            return None;
        }
        let out = if ca != 0 { ca } else { cb };
        let d = b - a;
        let p = if out & L != 0 {
            DVec2::new(0.0, a.y + d.y * (0.0 - a.x) / d.x)
        } else if out & R != 0 {
            DVec2::new(max.x, a.y + d.y * (max.x - a.x) / d.x)
        } else if out & T != 0 {
            DVec2::new(a.x + d.x * (0.0 - a.y) / d.y, 0.0)
        } else {
            DVec2::new(a.x + d.x * (max.y - a.y) / d.y, max.y)
        };
        if out == ca {
            a = p;
            ca = region(a, max);
        } else {
            b = p;
            cb = region(b, max);
        }
    }
    None
}

/// Draws a line between window points (pixel units, y down, centers at +0.5) into a color
/// plane of `width × height`.
pub fn draw_line(color: &mut [[u8; 4]], width: u32, height: u32, a: DVec2, b: DVec2, rgba: [u8; 4]) {
    let half = DVec2::splat(0.5);
    let max = DVec2::new(width as f64 - 1.0, height as f64 - 1.0);
    let Some((a, b)) = clip_segment(a - half, b - half, max) else {
        return;
    };
    let (x0, y0) = (a.x.round() as i32, a.y.round() as i32);
    let (x1, y1) = (b.x.round() as i32, b.y.round() as i32);
    let w = width as usize;
    bresenham(x0, y0, x1, y1, |x, y| {
        if let Some(p) = color.get_mut(y as usize * w + x as usize) {
            *p = rgba;
        }
    });
}

/// Draws the line between window points `a`, `b` (x, y in pixels, z window depth) of an edge
/// of triangle `id` into `fb.color`, where the depth buffer shows it (see the module doc).
pub fn draw_visible_line(fb: &mut Framebuffer, a: DVec3, b: DVec3, id: u32, rgba: [u8; 4]) {
    let (w, h) = (fb.width(), fb.height());
    let half = DVec2::splat(0.5);
    let max = DVec2::new(w as f64 - 1.0, h as f64 - 1.0);
    let (a2, b2) = (a.truncate(), b.truncate());
    let Some((p, q)) = clip_segment(a2 - half, b2 - half, max) else {
        return;
    };
    let d = b2 - a2;
    let len2 = d.length_squared();
    // Neighbours across the line: along y for a line running mostly along x, and so on.
    let across: [(i64, i64); 2] = if d.x.abs() >= d.y.abs() { [(0, -1), (0, 1)] } else { [(-1, 0), (1, 0)] };
    let (x0, y0) = (p.x.round() as i32, p.y.round() as i32);
    let (x1, y1) = (q.x.round() as i32, q.y.round() as i32);
    bresenham(x0, y0, x1, y1, |x, y| {
        if x < 0 || y < 0 || x >= w as i32 || y >= h as i32 {
            return;
        }
        let i = fb.index(x as u32, y as u32);
        let visible = fb.ids[i] == id || {
            let c = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let t = if len2 > 0.0 { ((c - a2).dot(d) / len2).clamp(0.0, 1.0) } else { 0.0 };
            let z = a.z + (b.z - a.z) * t;
            let stored = fb.depth[i];
            let mut slope = 0.0f32;
            for (dx, dy) in across {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx >= 0 && ny >= 0 && nx < w as i64 && ny < h as i64 {
                    let j = fb.index(nx as u32, ny as u32);
                    if fb.ids[j] == fb.ids[i] {
                        slope = slope.max((fb.depth[j] - stored).abs());
                    }
                }
            }
            let ulp = f32::from_bits(stored.to_bits() + 1) - stored;
            z <= stored as f64 + 0.5 * slope as f64 + 4.0 * ulp as f64
        };
        if visible {
            fb.color[i] = rgba;
        }
    });
}

/// Clips a clip-space segment to the near plane (`z ≥ −w`, and `w > 0`) and projects it to
/// window coordinates (x, y and window depth).
fn project_segment(mut a: Vec4, mut b: Vec4, width: u32, height: u32) -> Option<(DVec3, DVec3)> {
    // Near plane, then w > 0 (parallel projections have w = 1 and never fail it).
    let planes: [fn(Vec4) -> f32; 2] = [|c| c.z + c.w, |c| c.w - 1e-6];
    for dist in planes {
        let (da, db) = (dist(a), dist(b));
        if da < 0.0 && db < 0.0 {
            return None;
        }
        if da < 0.0 {
            a += (b - a) * (da / (da - db));
        } else if db < 0.0 {
            b += (a - b) * (db / (db - da));
        }
    }
    let win = |c: Vec4| {
        let (x, y, z, w) = (c.x as f64, c.y as f64, c.z as f64, c.w as f64);
        DVec3::new((x / w + 1.0) * 0.5 * width as f64, (1.0 - y / w) * 0.5 * height as f64, (z / w + 1.0) * 0.5)
    };
    Some((win(a), win(b)))
}

/// Draws the edges of the items' triangles over `fb.color` (back faces skipped when
/// culling is on); in [`Wireframe::HiddenLine`] mode only where they are visible in the
/// depth buffer `fb` holds (see the module doc).
pub fn draw_wireframe(
    scene: &Scene,
    instances: &[Instance],
    items: &[DrawItem],
    camera: &Camera,
    fb: &mut Framebuffer,
    opts: &RenderOptions,
) -> Result<()> {
    let (w, h) = (fb.width(), fb.height());
    for d in items {
        let inst = instances
            .get(d.instance as usize)
            .ok_or_else(|| Error::InvalidDraw(format!("instance {} out of range", d.instance)))?;
        let mesh = scene.try_mesh(inst.mesh)?;
        let m = camera.clip_from_local(&inst.world_from_local);
        let end = (d.first as usize + d.count as usize).min(mesh.triangle_count());
        for t in d.first as usize..end {
            let c = mesh.triangle_positions(t).map(|p| m * p.extend(1.0));
            if opts.backface_culling && crate::clip::facing_det(c) < 0.0 {
                continue;
            }
            let id = crate::triangle_id(inst.first_triangle, t as u32);
            for k in 0..3 {
                if let Some((a, b)) = project_segment(c[k], c[(k + 1) % 3], w, h) {
                    if opts.wireframe == Wireframe::HiddenLine {
                        draw_visible_line(fb, a, b, id, opts.wire_color);
                    } else {
                        draw_line(&mut fb.color, w, h, a.truncate(), b.truncate(), opts.wire_color);
                    }
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(x0: i32, y0: i32, x1: i32, y1: i32) -> Vec<(i32, i32)> {
        let mut v = Vec::new();
        bresenham(x0, y0, x1, y1, |x, y| v.push((x, y)));
        v
    }

    #[test]
    fn bresenham_all_octants_hit_both_ends_with_unit_steps() {
        for (x1, y1) in
            [(7, 3), (3, 7), (-3, 7), (-7, 3), (-7, -3), (-3, -7), (3, -7), (7, -3), (0, 0), (5, 5), (0, -4)]
        {
            let p = line(0, 0, x1, y1);
            assert_eq!(p[0], (0, 0));
            assert_eq!(*p.last().unwrap(), (x1, y1));
            assert_eq!(p.len() as i32, x1.abs().max(y1.abs()) + 1);
            for w in p.windows(2) {
                assert!((w[1].0 - w[0].0).abs() <= 1 && (w[1].1 - w[0].1).abs() <= 1);
            }
        }
        assert_eq!(line(0, 0, 5, 2), vec![(0, 0), (1, 0), (2, 1), (3, 1), (4, 2), (5, 2)]);
    }

    #[test]
    fn cohen_sutherland_clips_to_the_box() {
        let max = DVec2::new(9.0, 9.0);
        let (a, b) = clip_segment(DVec2::new(-5.0, 5.0), DVec2::new(15.0, 5.0), max).unwrap();
        assert_eq!((a, b), (DVec2::new(0.0, 5.0), DVec2::new(9.0, 5.0)));
        assert!(clip_segment(DVec2::new(-5.0, -1.0), DVec2::new(-1.0, -5.0), max).is_none());
        assert!(clip_segment(DVec2::new(-1.0, 0.5), DVec2::new(0.5, -1.0), max).is_none());
        let (a, b) = clip_segment(DVec2::new(-1.0, -1.0), DVec2::new(10.0, 10.0), max).unwrap();
        assert_eq!((a, b), (DVec2::ZERO, max));
        assert!(clip_segment(DVec2::new(f64::NAN, 0.0), DVec2::ZERO, max).is_none());
    }

    #[test]
    fn lines_stay_inside_the_image() {
        let mut c = vec![[0u8; 4]; 16];
        draw_line(&mut c, 4, 4, DVec2::new(-1e30, 2.5), DVec2::new(1e30, 2.5), [9; 4]);
        assert_eq!(c.iter().filter(|p| p[0] == 9).count(), 4);
        assert!(c[8..12].iter().all(|p| p[0] == 9));
    }
}

//! Primary rays: one per pixel through its center, from exactly the rasterizer's camera.
//!
//! Pixel (c, r) has NDC `x = 2(c + ½)/W − 1`, `y = 1 − 2(r + ½)/H` (row 0 at the top), and its
//! ray is [`Camera::ray_through_ndc`]'s, evaluated in f64 as that function does: the
//! projection's view-space ray mapped to world by the view basis, then rounded to f32. The
//! view-space x part depends on the column only and the y part on the row only, so both are
//! tabulated once per frame. Each ray's search interval is the part of the line between the
//! near and far planes, measured along the gaze (view depth), which is exactly the part the
//! rasterizer keeps after clipping.

use glam::{DVec2, DVec3, Vec3A};
use sightline_scene::Camera;

use super::packet::{Beam, Hits, Rays, CHUNK, CHUNKS, TILE};

/// Per-frame ray generator.
#[derive(Debug, Clone)]
pub(crate) struct CameraRays {
    eye: DVec3,
    u: DVec3,
    v: DVec3,
    w: DVec3,
    /// Unit gaze (−w).
    gaze: DVec3,
    near: f64,
    far: f64,
    /// True when all rays start at the eye.
    pub perspective: bool,
    /// The eye in f32 (the shared origin of perspective rays).
    pub eye32: Vec3A,
    /// View-space (origin x, direction x) per pixel column.
    cols: Vec<[f64; 2]>,
    /// View-space (origin y, direction y) per pixel row.
    rows: Vec<[f64; 2]>,
    /// View-space (origin z, direction z), the same for every pixel.
    z: [f64; 2],
    width: u32,
    height: u32,
}

impl CameraRays {
    /// The generator for a `width × height` image.
    pub fn new(camera: &Camera, width: u32, height: u32) -> Self {
        let p = &camera.projection;
        let (w_, h_) = (width as f64, height as f64);
        let cols = (0..width)
            .map(|c| {
                let (o, d) = p.view_ray(DVec2::new(Self::ndc_x(c as f64 + 0.5, w_), 0.0));
                [o.x, d.x]
            })
            .collect();
        let rows = (0..height)
            .map(|r| {
                let (o, d) = p.view_ray(DVec2::new(0.0, Self::ndc_y(r as f64 + 0.5, h_)));
                [o.y, d.y]
            })
            .collect();
        let (o, d) = p.view_ray(DVec2::ZERO);
        let view = &camera.view;
        let w = view.w.as_dvec3();
        Self {
            eye: view.eye.as_dvec3(),
            u: view.u.as_dvec3(),
            v: view.v.as_dvec3(),
            w,
            gaze: -w,
            near: p.near() as f64,
            far: p.far() as f64,
            perspective: p.is_perspective(),
            eye32: Vec3A::from(view.eye),
            cols,
            rows,
            z: [o.z, d.z],
            width,
            height,
        }
    }

    #[inline]
    fn ndc_x(x: f64, w: f64) -> f64 {
        2.0 * x / w - 1.0
    }

    #[inline]
    fn ndc_y(y: f64, h: f64) -> f64 {
        1.0 - 2.0 * y / h
    }

    #[inline(always)]
    fn to_world(&self, p: DVec3) -> DVec3 {
        self.u * p.x + self.v * p.y + self.w * p.z
    }

    /// The ray of pixel (c, r): (origin, direction) in world space.
    #[cfg(test)]
    pub fn ray(&self, c: u32, r: u32) -> (Vec3A, Vec3A) {
        let [ox, dx] = self.cols[c as usize];
        let [oy, dy] = self.rows[r as usize];
        let o = self.eye + self.to_world(DVec3::new(ox, oy, self.z[0]));
        let d = self.to_world(DVec3::new(dx, dy, self.z[1]));
        (o.as_vec3().into(), d.as_vec3().into())
    }

    /// Fills the 8 × 8 packet whose top-left pixel is (x0, y0): rays, reciprocals, shears and
    /// near–far intervals. Returns the mask of lanes inside the image with a valid
    /// interval; the other lanes get empty intervals.
    #[inline(always)]
    pub fn fill(&self, x0: u32, y0: u32, rays: &mut Rays, hits: &mut Hits) -> u64 {
        let (w, h) = (self.width, self.height);
        let mut inside = 0u64;
        for ly in 0..TILE {
            let r = (y0 + ly).min(h - 1);
            let [oy, dy] = self.rows[r as usize];
            let (c, j0) = ((ly / 2) as usize, ((ly % 2) * TILE) as usize);
            for lx in 0..TILE {
                let col = (x0 + lx).min(w - 1);
                let [ox, dx] = self.cols[col as usize];
                let d = self.to_world(DVec3::new(dx, dy, self.z[1]));
                let j = j0 + lx as usize;
                rays.d[0][c][j] = d.x as f32;
                rays.d[1][c][j] = d.y as f32;
                rays.d[2][c][j] = d.z as f32;
                let o =
                    if self.perspective { self.eye } else { self.eye + self.to_world(DVec3::new(ox, oy, self.z[0])) };
                rays.o[0][c][j] = o.x as f32;
                rays.o[1][c][j] = o.y as f32;
                rays.o[2][c][j] = o.z as f32;
            }
            if y0 + ly < h {
                let cols = (w.saturating_sub(x0)).min(TILE);
                inside |= ((1u64 << cols) - 1) << (ly * TILE);
            }
        }
        rays.shared = self.perspective.then_some(self.eye32);
        let g = self.gaze;
        let mut mask = 0u64;
        for c in 0..CHUNKS {
            let mut m = 0u64;
            rays.derive_chunk(c);
            for j in 0..CHUNK {
                let d = [rays.d[0][c][j], rays.d[1][c][j], rays.d[2][c][j]];
                let dg = g.x * d[0] as f64 + g.y * d[1] as f64 + g.z * d[2] as f64;
                let og = if self.perspective {
                    0.0
                } else {
                    g.x * (rays.o[0][c][j] as f64 - self.eye.x)
                        + g.y * (rays.o[1][c][j] as f64 - self.eye.y)
                        + g.z * (rays.o[2][c][j] as f64 - self.eye.z)
                };
                let t0 = (self.near - og) / dg;
                let t0 = if t0 > 0.0 { t0 } else { 0.0 };
                let t1 = (self.far - og) / dg;
                let ok = (dg > 0.0) & (t1 > t0) & (t1 < f64::INFINITY);
                hits.tmin[c][j] = if ok { t0 as f32 } else { f32::INFINITY };
                hits.t[c][j] = if ok { t1 as f32 } else { f32::NEG_INFINITY };
                hits.inst[c][j] = super::packet::NO_HIT;
                hits.gid[c][j] = super::packet::NO_GID;
                m |= (ok as u64) << j;
            }
            mask |= m << (c * CHUNK);
        }
        mask & inside
    }

    /// The ray through a window position (pixel units, y down), not necessarily a center.
    pub fn ray_at(&self, x: f64, y: f64, camera: &Camera) -> (Vec3A, Vec3A) {
        let ndc = DVec2::new(Self::ndc_x(x, self.width as f64), Self::ndc_y(y, self.height as f64));
        let (o, d) = camera.projection.view_ray(ndc);
        ((self.eye + self.to_world(o)).as_vec3().into(), self.to_world(d).as_vec3().into())
    }

    /// The corner rays of the pixel block `[x0, x1) × [y0, y1)` (at pixel corners).
    pub fn beam(&self, x0: u32, y0: u32, x1: u32, y1: u32, camera: &Camera) -> Beam {
        let pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)];
        let rays = pts.map(|(x, y)| self.ray_at(x as f64, y as f64, camera));
        Beam { o: rays.map(|r| r.0), d: rays.map(|r| r.1) }
    }

    /// The `[t_near, t_far]` of a ray between the near and far planes; `None` for rays that
    /// do not move forward (zero, NaN or backwards directions).
    #[cfg(test)]
    pub fn interval(&self, o: Vec3A, d: Vec3A) -> Option<(f32, f32)> {
        let og = self.gaze.dot(o.as_dvec3() - self.eye);
        let dg = self.gaze.dot(d.as_dvec3());
        if dg.is_nan() || dg <= 0.0 || !dg.is_finite() || !og.is_finite() {
            return None;
        }
        let t0 = ((self.near - og) / dg).max(0.0);
        let t1 = (self.far - og) / dg;
        (t1 > t0).then_some((t0 as f32, t1 as f32))
    }

    /// NDC of a pixel center, as the brief of [`Camera::ray_through_ndc`] takes it.
    #[cfg(test)]
    pub fn ndc(&self, c: u32, r: u32) -> glam::Vec2 {
        glam::Vec2::new(
            Self::ndc_x(c as f64 + 0.5, self.width as f64) as f32,
            Self::ndc_y(r as f64 + 0.5, self.height as f64) as f32,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use sightline_scene::{Projection, View};

    #[test]
    fn rays_equal_the_cameras_own() {
        let view = View::look_at(Vec3::new(1.0, 2.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        let cams = [
            Camera::new(view, Projection::perspective(sightline_scene::Angle::radians(1.0), 1.0, 0.1, 100.0).unwrap())
                .unwrap(),
            Camera::new(view, Projection::orthographic(-2.0, 2.0, -2.0, 2.0, 0.5, 50.0).unwrap()).unwrap(),
            Camera::new(view, Projection::cabinet(-2.0, 2.0, -2.0, 2.0, 0.5, 50.0, 0.5).unwrap()).unwrap(),
        ];
        for cam in cams {
            // 8 × 8 pixels: every NDC value is exact in f32, so the rays must match bit for bit.
            let g = CameraRays::new(&cam, 8, 8);
            for r in 0..8 {
                for c in 0..8 {
                    let (o, d) = g.ray(c, r);
                    let (o2, d2) = cam.ray_through_ndc(g.ndc(c, r));
                    assert_eq!((Vec3::from(o), Vec3::from(d)), (o2, d2));
                    let (t0, t1) = g.interval(o, d).unwrap();
                    let depth = |t: f32| -(cam.view.view_from_world().transform_point3(o2 + d2 * t)).z;
                    assert!((depth(t0) - cam.projection.near()).abs() < 1e-4);
                    assert!((depth(t1) / cam.projection.far() - 1.0).abs() < 1e-5);
                }
            }
        }
    }

    #[test]
    fn packets_hold_the_pixel_rays() {
        let view = View::look_at(Vec3::new(1.0, 2.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        for p in [
            Projection::perspective(sightline_scene::Angle::radians(1.0), 1.3, 0.1, 100.0).unwrap(),
            Projection::cavalier(-2.0, 2.0, -2.0, 2.0, 0.5, 50.0, 0.3).unwrap(),
        ] {
            let cam = Camera::new(view, p).unwrap();
            // 13 × 11: partial packets at the right and bottom.
            let g = CameraRays::new(&cam, 13, 11);
            let (mut rays, mut hits) = (Rays::new(), Hits::new());
            for (x0, y0) in [(0, 0), (8, 0), (0, 8), (8, 8)] {
                let mask = g.fill(x0, y0, &mut rays, &mut hits);
                for i in 0..64 {
                    let (c, r) = (x0 + i as u32 % 8, y0 + i as u32 / 8);
                    let inside = c < 13 && r < 11;
                    assert_eq!(mask >> i & 1 == 1, inside);
                    if inside {
                        let (o, d) = g.ray(c, r);
                        assert_eq!((rays.origin(i), rays.dir(i)), (o, d));
                        assert_eq!(hits.range(i), g.interval(o, d).unwrap());
                        assert_eq!(rays.shared.is_some(), p.is_perspective());
                    }
                }
            }
        }
    }
}

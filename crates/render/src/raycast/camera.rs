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

use super::isa::Isa;
#[cfg(test)]
use super::packet::Beam;
use super::packet::{BeamPlanes, Hits, Rays, CHUNK, CHUNKS, TILE};

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
    #[cfg(test)]
    cols: Vec<[f64; 2]>,
    /// View-space (origin y, direction y) per pixel row.
    #[cfg(test)]
    rows: Vec<[f64; 2]>,
    /// View-space (origin z, direction z), the same for every pixel.
    #[cfg(test)]
    z: [f64; 2],
    /// Per column, `u·dx` and `u·ox` (world-space products of [`CameraRays::to_world`]'s
    /// first term), so a packet only adds.
    col_terms: Vec<[[f64; 3]; 2]>,
    /// Per row, `v·dy` and `v·oy`.
    row_terms: Vec<[[f64; 3]; 2]>,
    /// `w·dz` and `w·oz`.
    z_terms: [[f64; 3]; 2],
    /// View-space (origin x, direction x) per pixel *corner* column (`width + 1` of them),
    /// for the packets' beams.
    corner_cols: Vec<[f64; 2]>,
    /// View-space (origin y, direction y) per pixel corner row (`height + 1`).
    corner_rows: Vec<[f64; 2]>,
    /// View-space (origin z, direction z), the same for every ray.
    view_z: [f64; 2],
    /// Per packet row boundary `k` (pixel corner row `min(8k, height)`), the plane holding
    /// every ray through that corner row as `(n, c)` with `n·x + c ≥ 0` below it (`None`:
    /// degenerate); a packet's top and bottom beam planes are two of these.
    row_planes: Vec<Option<[f32; 4]>>,
    /// Per packet column boundary (corner column `min(8k, width)`), likewise, with the
    /// columns to the right inside; a packet's left and right beam planes.
    col_planes: Vec<Option<[f32; 4]>>,
    width: u32,
    height: u32,
}

impl CameraRays {
    /// The generator for a `width × height` image.
    pub fn new(camera: &Camera, width: u32, height: u32) -> Self {
        let p = &camera.projection;
        let (w_, h_) = (width as f64, height as f64);
        let cols: Vec<[f64; 2]> = (0..width)
            .map(|c| {
                let (o, d) = p.view_ray(DVec2::new(Self::ndc_x(c as f64 + 0.5, w_), 0.0));
                [o.x, d.x]
            })
            .collect();
        let rows: Vec<[f64; 2]> = (0..height)
            .map(|r| {
                let (o, d) = p.view_ray(DVec2::new(0.0, Self::ndc_y(r as f64 + 0.5, h_)));
                [o.y, d.y]
            })
            .collect();
        let corner_cols = (0..=width)
            .map(|c| {
                let (o, d) = p.view_ray(DVec2::new(Self::ndc_x(c as f64, w_), 0.0));
                [o.x, d.x]
            })
            .collect();
        let corner_rows = (0..=height)
            .map(|r| {
                let (o, d) = p.view_ray(DVec2::new(0.0, Self::ndc_y(r as f64, h_)));
                [o.y, d.y]
            })
            .collect();
        let (o, d) = p.view_ray(DVec2::ZERO);
        let view = &camera.view;
        let w = view.w.as_dvec3();
        let (u, v) = (view.u.as_dvec3(), view.v.as_dvec3());
        let terms = |axis: DVec3, [o, d]: [f64; 2]| [(axis * d).to_array(), (axis * o).to_array()];
        let col_terms = cols.iter().map(|&c| terms(u, c)).collect();
        let row_terms = rows.iter().map(|&r| terms(v, r)).collect();
        let z_terms = terms(w, [o.z, d.z]);
        let mut g = Self {
            col_terms,
            row_terms,
            z_terms,
            corner_cols,
            corner_rows,
            view_z: [o.z, d.z],
            row_planes: Vec::new(),
            col_planes: Vec::new(),
            eye: view.eye.as_dvec3(),
            u: view.u.as_dvec3(),
            v: view.v.as_dvec3(),
            w,
            gaze: -w,
            near: p.near() as f64,
            far: p.far() as f64,
            perspective: p.is_perspective(),
            eye32: Vec3A::from(view.eye),
            #[cfg(test)]
            cols,
            #[cfg(test)]
            rows,
            #[cfg(test)]
            z: [o.z, d.z],
            width,
            height,
        };
        let bounds = |n: u32| (0..=n.div_ceil(TILE)).map(move |k| (k * TILE).min(n));
        g.row_planes = bounds(height).map(|y| g.boundary_plane((0, y), (width, y), (width / 2, y), false)).collect();
        g.col_planes = bounds(width).map(|x| g.boundary_plane((x, 0), (x, height), (x, height / 2), true)).collect();
        g
    }

    /// The world ray through pixel corner (x, y), in f64.
    fn corner_ray(&self, (x, y): (u32, u32)) -> (DVec3, DVec3) {
        let [ox, dx] = self.corner_cols[(x as usize).min(self.width as usize)];
        let [oy, dy] = self.corner_rows[(y as usize).min(self.height as usize)];
        (
            self.eye + self.to_world(DVec3::new(ox, oy, self.view_z[0])),
            self.to_world(DVec3::new(dx, dy, self.view_z[1])),
        )
    }

    /// The plane holding the corner rays through `a` and `b` (every ray of a pixel-corner row
    /// or column: the rays of a pinhole or parallel camera through a line of the image lie in
    /// one plane), oriented so that the rays next to corner `m` on the side of larger image
    /// y (`column`: larger x) are inside. `None` when degenerate.
    fn boundary_plane(&self, a: (u32, u32), b: (u32, u32), m: (u32, u32), column: bool) -> Option<[f32; 4]> {
        let ((oa, da), (ob, db)) = (self.corner_ray(a), self.corner_ray(b));
        // Perspective: oa = ob, n = da × db. Parallel: da = db, n = d × (ob − oa).
        let n = da.cross(ob + db - oa);
        let c = -n.dot(oa);
        // A point on a ray one pixel past the boundary, or before it at the image's end.
        let (last, (mx, my)) = if column { (m.0 >= self.width, m) } else { (m.1 >= self.height, m) };
        let step = |v: u32| if last { v.saturating_sub(1) } else { v + 1 };
        let probe = if column { (step(mx), my) } else { (mx, step(my)) };
        let (op, dp) = self.corner_ray(probe);
        let side = n.dot(op + dp) + c;
        let (n, c) = if (side < 0.0) != last { (-n, -c) } else { (n, c) };
        let f = [n.x as f32, n.y as f32, n.z as f32, c as f32];
        (f.iter().all(|v| v.is_finite()) && f[..3].iter().any(|&v| v != 0.0) && side != 0.0).then_some(f)
    }

    /// The four side planes of the packet whose top-left pixel is (x0, y0), oriented inwards,
    /// read from the per-frame boundary planes (culling off when one is degenerate).
    #[inline]
    pub fn frustum(&self, x0: u32, y0: u32) -> BeamPlanes {
        let (kx, ky) = ((x0 / TILE) as usize, (y0 / TILE) as usize);
        let flip = |p: [f32; 4]| p.map(|v| -v);
        let planes = [
            self.row_planes.get(ky).copied().flatten(),
            self.col_planes.get(kx + 1).copied().flatten().map(flip),
            self.row_planes.get(ky + 1).copied().flatten().map(flip),
            self.col_planes.get(kx).copied().flatten(),
        ];
        let mut f = BeamPlanes::OFF;
        if planes.iter().all(Option::is_some) {
            f.on = true;
            for (k, p) in planes.into_iter().flatten().enumerate() {
                for (n, v) in f.n.iter_mut().zip(p) {
                    n[k] = v;
                }
                f.c[k] = p[3];
            }
        }
        f
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
    ///
    /// A world direction is `(u·dx + v·dy) + w·dz`, the same sum [`CameraRays::to_world`]
    /// rounds, from products tabulated per column and row: bit for bit the camera's ray, with
    /// only additions per pixel, a row of eight lanes per loop.
    // Index loops over SoA lanes: the form LLVM vectorizes.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    pub fn fill<I: Isa>(&self, x0: u32, y0: u32, rays: &mut Rays, hits: &mut Hits) -> u64 {
        let (w, h) = (self.width, self.height);
        let tile = TILE as usize;
        // The packet's column terms, SoA: [d or o][axis][lx].
        let mut ct = [[[0f64; TILE as usize]; 3]; 2];
        for lx in 0..tile {
            let col = (x0 + lx as u32).min(w - 1) as usize;
            for (k, t) in self.col_terms[col].iter().enumerate() {
                for a in 0..3 {
                    ct[k][a][lx] = t[a];
                }
            }
        }
        let [wd, wo] = self.z_terms;
        let (g, eye) = (self.gaze.to_array(), self.eye.to_array());
        let mut inside = 0u64;
        for ly in 0..tile {
            let r = (y0 + ly as u32).min(h - 1) as usize;
            let [rd, ro] = self.row_terms[r];
            let (c, j0) = (ly / 2, (ly % 2) * tile);
            for lx in 0..tile {
                let j = j0 + lx;
                let d = [0, 1, 2].map(|a| ((ct[0][a][lx] + rd[a]) + wd[a]) as f32);
                for a in 0..3 {
                    rays.d[a][c][j] = d[a];
                }
                let o = if self.perspective {
                    eye.map(|e| e as f32)
                } else {
                    [0, 1, 2].map(|a| (eye[a] + ((ct[1][a][lx] + ro[a]) + wo[a])) as f32)
                };
                for a in 0..3 {
                    rays.o[a][c][j] = o[a];
                }
                // The search interval, by view depth along the gaze.
                let dg = g[0] * d[0] as f64 + g[1] * d[1] as f64 + g[2] * d[2] as f64;
                let og = if self.perspective {
                    0.0
                } else {
                    g[0] * (o[0] as f64 - eye[0]) + g[1] * (o[1] as f64 - eye[1]) + g[2] * (o[2] as f64 - eye[2])
                };
                // The interval's ends share one reciprocal of `dg` (a division costs several
                // multiplications); this is the interval's definition, `interval` below
                // computes the same.
                let rdg = 1.0 / dg;
                let t0 = (self.near - og) * rdg;
                let t0 = if t0 > 0.0 { t0 } else { 0.0 };
                let t1 = (self.far - og) * rdg;
                let ok = (dg > 0.0) & (t1 > t0) & (t1 < f64::INFINITY);
                hits.tmin[c][j] = if ok { t0 as f32 } else { f32::INFINITY };
                hits.t[c][j] = if ok { t1 as f32 } else { f32::NEG_INFINITY };
                hits.inst[c][j] = super::packet::NO_HIT;
                hits.gid[c][j] = super::packet::NO_GID;
            }
            if y0 + (ly as u32) < h {
                let cols = (w.saturating_sub(x0)).min(TILE);
                inside |= ((1u64 << cols) - 1) << (ly * tile);
            }
        }
        rays.shared = self.perspective.then_some(self.eye32);
        for c in 0..CHUNKS {
            rays.derive_chunk(c);
        }
        // Lanes with an interval: `t1 > t0` survives rounding to f32 as `tmin ≤ t`, and a lane
        // without one has (∞, −∞). Compared per chunk in SIMD: a bit mask built lane by lane
        // in the loop above is what auto-vectorization does badly (see `isa`).
        let mut mask = 0u64;
        for c in 0..CHUNKS {
            // SAFETY: `I` is only instantiated for an instruction set the CPU has.
            mask |= unsafe { I::le16(&hits.tmin[c], &hits.t[c]) } << (c * CHUNK);
        }
        mask & inside
    }

    /// The ray through a window position (pixel units, y down), not necessarily a center.
    #[cfg(test)]
    pub fn ray_at(&self, x: f64, y: f64, camera: &Camera) -> (Vec3A, Vec3A) {
        let ndc = DVec2::new(Self::ndc_x(x, self.width as f64), Self::ndc_y(y, self.height as f64));
        let (o, d) = camera.projection.view_ray(ndc);
        ((self.eye + self.to_world(o)).as_vec3().into(), self.to_world(d).as_vec3().into())
    }

    /// The corner rays of the pixel block `[x0, x1) × [y0, y1)` (at pixel corners; the
    /// corners lie inside the image's `(width + 1) × (height + 1)` grid). The view-space
    /// ray's x part depends on the column only and its y part on the row only, so the
    /// corners come from tables: the same rays as [`CameraRays::ray_at`] gives there. (The
    /// reference the tests hold [`CameraRays::frustum`]'s planes to.)
    #[cfg(test)]
    pub fn beam(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> Beam {
        let (w, h) = (self.width as usize, self.height as usize);
        let pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)];
        let rays = pts.map(|(x, y)| {
            let [ox, dx] = self.corner_cols[(x as usize).min(w)];
            let [oy, dy] = self.corner_rows[(y as usize).min(h)];
            let o = self.eye + self.to_world(DVec3::new(ox, oy, self.view_z[0]));
            let d = self.to_world(DVec3::new(dx, dy, self.view_z[1]));
            (Vec3A::from(o.as_vec3()), Vec3A::from(d.as_vec3()))
        });
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
        let rdg = 1.0 / dg;
        let t0 = ((self.near - og) * rdg).max(0.0);
        let t1 = (self.far - og) * rdg;
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
    use crate::raycast::isa::Portable;
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
                let mask = g.fill::<Portable>(x0, y0, &mut rays, &mut hits);
                // The beam's corners: the rays through the packet's pixel corners, clamped to
                // the image.
                let b = g.beam(x0, y0, x0 + 8, y0 + 8);
                for (k, (x, y)) in [(x0, y0), (x0 + 8, y0), (x0 + 8, y0 + 8), (x0, y0 + 8)].into_iter().enumerate() {
                    assert_eq!((b.o[k], b.d[k]), g.ray_at(x.min(13) as f64, y.min(11) as f64, &cam));
                }
                // The packet's frustum from the per-frame boundary planes: the planes of the
                // beam's own corner rays, and it keeps every lane's ray from near to far.
                let (fr, fb) = (g.frustum(x0, y0), b.frustum());
                assert!(fr.on && fb.on);
                for k in 0..4 {
                    let n = |f: &BeamPlanes| Vec3::new(f.n[0][k], f.n[1][k], f.n[2][k]).normalize();
                    assert!(n(&fr).dot(n(&fb)) > 0.99999, "plane {k} of packet ({x0}, {y0})");
                }
                let culled = |p: Vec3| fr.culls(&(p - 1e-4).to_array(), &(p + 1e-4).to_array());
                for i in (0..64).filter(|i| mask >> i & 1 == 1) {
                    let (o, d) = (Vec3::from(rays.origin(i)), Vec3::from(rays.dir(i)));
                    let (t0, t1) = hits.range(i);
                    for t in [t0, 0.5 * (t0 + t1), t1] {
                        assert!(!culled(o + d * t), "lane {i} of packet ({x0}, {y0}) at t = {t}");
                    }
                }
                // A ray two pixels left of the packet, halfway along: outside.
                if x0 >= 8 {
                    let (o, d) = g.ray(x0 - 2, y0);
                    let (t0, t1) = g.interval(o, d).unwrap();
                    assert!(culled(Vec3::from(o + d * (0.5 * (t0 + t1)))));
                }
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

    /// The packets' beam planes from the per-frame boundary tables, as the traversal uses
    /// them (`culls4`): every packet of images down to one pixel, three kinds of projection.
    /// Each plane keeps every ray of its packet from near to far, and the rays of the pixels
    /// just outside each side are culled.
    #[test]
    fn boundary_planes_keep_each_packets_rays_and_cull_its_neighbours() {
        let view = View::look_at(Vec3::new(1.0, 2.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        let projections = [
            Projection::perspective(sightline_scene::Angle::radians(1.0), 1.3, 0.1, 100.0).unwrap(),
            Projection::orthographic(-2.0, 2.0, -1.5, 1.5, 0.5, 50.0).unwrap(),
            Projection::cavalier(-2.0, 2.0, -2.0, 2.0, 0.5, 50.0, 0.3).unwrap(),
        ];
        for p in projections {
            let cam = Camera::new(view, p).unwrap();
            for (w, h) in [(1, 1), (1, 17), (9, 1), (16, 16), (13, 11), (24, 9)] {
                let g = CameraRays::new(&cam, w, h);
                let point = |x: u32, y: u32, f: f32| {
                    let (o, d) = g.ray(x, y);
                    let (t0, t1) = g.interval(o, d).unwrap();
                    Vec3::from(o + d * (t0 + f * (t1 - t0)))
                };
                for y0 in (0..h).step_by(8) {
                    for x0 in (0..w).step_by(8) {
                        let fr = g.frustum(x0, y0);
                        assert!(fr.on);
                        let culled = |p: Vec3| {
                            let (mut lo, mut hi) = ([[f32::INFINITY; 4]; 3], [[f32::NEG_INFINITY; 4]; 3]);
                            for a in 0..3 {
                                (lo[a][0], hi[a][0]) = (p[a] - 1e-4, p[a] + 1e-4);
                            }
                            fr.culls4(&lo, &hi) & 1 == 1
                        };
                        let (x1, y1) = ((x0 + 8).min(w), (y0 + 8).min(h));
                        for y in y0..y1 {
                            for x in x0..x1 {
                                for f in [0.0, 0.5, 1.0] {
                                    assert!(!culled(point(x, y, f)), "{w}x{h}: pixel ({x}, {y}) at {f}");
                                }
                            }
                        }
                        let (xm, ym) = ((x0 + x1) / 2, (y0 + y1) / 2);
                        let outside = [
                            (x0 > 0).then(|| (x0 - 1, ym)),
                            (x1 < w).then_some((x1, ym)),
                            (y0 > 0).then(|| (xm, y0 - 1)),
                            (y1 < h).then_some((xm, y1)),
                        ];
                        for (x, y) in outside.into_iter().flatten() {
                            assert!(culled(point(x, y, 0.5)), "{w}x{h}: packet ({x0}, {y0}) keeps pixel ({x}, {y})");
                        }
                    }
                }
            }
        }
    }
}

use glam::{DVec2, DVec3, DVec4, Vec3};
use sightline_render::{render_scene, Framebuffer, RayCaster, RaycastOptions, RenderOptions};
use sightline_scene::builders::{city, CityParams};
use sightline_scene::{Camera, Projection, Scene, View};

fn reference(scene: &Scene, cam: &Camera, w: u32, h: u32) -> (Vec<u32>, Vec<f64>) {
    let mut tris = Vec::new();
    for inst in scene.instances() {
        let m = scene.mesh(inst.mesh).unwrap();
        let a = glam::DMat4::from(glam::Mat4::from(inst.world_from_local).as_dmat4());
        for t in 0..m.triangle_count() {
            let p = m.triangle_positions(t).map(|v| a.transform_point3(v.as_dvec3()));
            tris.push((p, inst.first_triangle + t as u32 + 1));
        }
    }
    let clip = cam.clip_from_world_f64();
    let (u, v, ww) = (cam.view.u.as_dvec3(), cam.view.v.as_dvec3(), cam.view.w.as_dvec3());
    let eye = cam.view.eye.as_dvec3();
    let mut ids = vec![0; (w * h) as usize];
    let mut depth = vec![1.0; (w * h) as usize];
    for r in 0..h {
        for c in 0..w {
            let ndc = DVec2::new(2.0 * (c as f64 + 0.5) / w as f64 - 1.0, 1.0 - 2.0 * (r as f64 + 0.5) / h as f64);
            let (o, d) = cam.projection.view_ray(ndc);
            let o = eye + u * o.x + v * o.y + ww * o.z;
            let d = u * d.x + v * d.y + ww * d.z;
            let g = -ww;
            let t0 = (cam.projection.near() as f64 - g.dot(o - eye)) / g.dot(d);
            let t1 = (cam.projection.far() as f64 - g.dot(o - eye)) / g.dot(d);
            let mut best = (f64::INFINITY, 0u32);
            for (p, id) in &tris {
                let e1 = p[1] - p[0];
                let e2 = p[2] - p[0];
                let pv = d.cross(e2);
                let det = e1.dot(pv);
                if det == 0.0 {
                    continue;
                }
                // back faces: front when det < 0 ... (MT det = e1·(d×e2) = -d·(e1×e2))
                if det < 0.0 {
                    continue;
                }
                let s = o - p[0];
                let uu = s.dot(pv) / det;
                if uu < 0.0 || uu > 1.0 {
                    continue;
                }
                let q = s.cross(e1);
                let vv = d.dot(q) / det;
                if vv < 0.0 || uu + vv > 1.0 {
                    continue;
                }
                let t = e2.dot(q) / det;
                if t >= t0 && t <= t1 && t < best.0 {
                    best = (t, *id);
                }
            }
            let i = (r * w + c) as usize;
            if best.1 != 0 {
                ids[i] = best.1;
                let p = o + d * best.0;
                let cc = clip * DVec4::new(p.x, p.y, p.z, 1.0);
                depth[i] = (cc.z / cc.w + 1.0) * 0.5;
            }
        }
    }
    (ids, depth)
}

#[test]
fn dbg() {
    let c = city(&CityParams::for_triangles(30_000)).unwrap();
    let b = c.layout.bounds();
    let center = b.center();
    let (w, h) = (192u32, 108u32);
    let view = View::look_at(center + Vec3::new(150.0, 200.0, 120.0), center, Vec3::Y).unwrap();
    let r = b.extent().length() * 0.4;
    let cab = Projection::cabinet(-r, r, -r * 0.5625, r * 0.5625, 1.0, 1000.0, 0.5).unwrap();
    let aerial = c.layout.aerial_path(12);
    for cam in [Camera::new(view, cab).unwrap(), aerial[7].camera(w as f32 / h as f32).unwrap()] {
        let mut a = Framebuffer::new(w, h).unwrap();
        render_scene(&c.scene, &cam, &mut a, &RenderOptions::default()).unwrap();
        let caster = RayCaster::build(&c.scene).unwrap();
        let mut bb = Framebuffer::new(w, h).unwrap();
        caster.render(&cam, &RaycastOptions::default(), &mut bb).unwrap();
        let (rid, rd) = reference(&c.scene, &cam, w, h);
        let (mut ra, mut rb, mut big_a, mut big_b, mut n) = (0, 0, 0, 0, 0);
        let (mut wa, mut wb) = (0f64, 0f64);
        for i in 0..a.len() {
            ra += (rid[i] == a.ids[i]) as u32;
            rb += (rid[i] == bb.ids[i]) as u32;
            if rid[i] != 0 && rid[i] == a.ids[i] && rid[i] == bb.ids[i] {
                n += 1;
                let da = (a.depth[i] as f64 - rd[i]).abs();
                let db = (bb.depth[i] as f64 - rd[i]).abs();
                wa = wa.max(da);
                wb = wb.max(db);
                big_a += (da > 1e-5) as u32;
                big_b += (db > 1e-5) as u32;
            }
        }
        eprintln!("ref agreement raster {} ray {} of {}; common {n}: raster depth max {wa:e} (>1e-5: {big_a}), ray depth max {wb:e} (>1e-5: {big_b})", ra, rb, a.len());
    }
}

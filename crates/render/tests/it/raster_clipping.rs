//! Clipping: triangles crossing the eye plane and the frustum sides, and one lying exactly
//! on the near plane, cover the same pixels as a brute-force per-pixel ray–triangle test.
//! Guard-band clipping (the default) gives the same IDs as full frustum clipping.

use glam::{DVec3, Vec3};
use sightline_render::{render_scene, Framebuffer, RenderOptions};
use sightline_scene::{Angle, Camera, LookAt, Mesh, Scene};

use crate::support::{one_node_scene, pixel_ndc};

const W: u32 = 64;
const H: u32 = 48;

fn scene_of(tri: [Vec3; 3]) -> Scene {
    one_node_scene("t", Mesh::new("t", tri.to_vec(), None, None, vec![0, 1, 2]).unwrap())
}

fn render(scene: &Scene, cam: &Camera, guard_band: bool) -> Framebuffer {
    let mut fb = Framebuffer::new(W, H).unwrap();
    let opts = RenderOptions { backface_culling: false, guard_band, ..RenderOptions::ids_only() };
    render_scene(scene, cam, &mut fb, &opts).unwrap();
    fb
}

/// Möller–Trumbore in f64: Some(smallest barycentric margin) when the ray hits the
/// triangle's plane at a parameter within [t_min, t_max].
fn ray_margin(o: DVec3, d: DVec3, tri: [DVec3; 3], t_min: f64, t_max: f64) -> Option<f64> {
    let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-300 {
        return None;
    }
    let s = o - tri[0];
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let v = d.dot(q) / det;
    let t = e2.dot(q) / det;
    if !(t >= t_min && t <= t_max) {
        return None;
    }
    Some(u.min(v).min(1.0 - u - v))
}

/// Compares covered pixels with the ray test; pixels within `eps` (barycentric) of an edge
/// are not judged. Returns how many pixels were judged.
fn check(tri: [Vec3; 3], cam: &Camera) -> usize {
    let scene = scene_of(tri);
    let fb = render(&scene, cam, true);
    let full = render(&scene, cam, false);
    assert_eq!(fb.ids, full.ids, "guard band and full clipping differ");
    let (near, far) = (cam.projection.near() as f64, cam.projection.far() as f64);
    let tri_d = tri.map(|v| v.as_dvec3());
    let mut judged = 0;
    for y in 0..H {
        for x in 0..W {
            let (o, d) = cam.ray_through_ndc(pixel_ndc(x, y, W, H));
            // The direction has view z = −1, so t is the view depth.
            let m = ray_margin(o.as_dvec3(), d.as_dvec3(), tri_d, near * (1.0 - 1e-9), far);
            let covered = fb.ids[fb.index(x, y)] == 1;
            match m {
                Some(m) if m > 1e-3 => assert!(covered, "pixel ({x},{y}) should be covered"),
                Some(m) if m > -1e-3 => continue,
                _ => assert!(!covered, "pixel ({x},{y}) should be empty"),
            }
            judged += 1;
            assert!(fb.depth[fb.index(x, y)].is_finite());
        }
    }
    judged
}

fn camera(near: f32, far: f32) -> Camera {
    Camera::perspective(
        &LookAt { eye: Vec3::ZERO, target: Vec3::NEG_Z, up: Vec3::Y, fovy: Angle::degrees(60.0), near, far },
        W as f32 / H as f32,
    )
    .unwrap()
}

#[test]
fn one_vertex_behind_the_eye() {
    let cam = camera(0.5, 100.0);
    let tri = [Vec3::new(-1.0, -0.5, -3.0), Vec3::new(1.0, -0.7, -3.0), Vec3::new(0.2, 0.5, 2.0)];
    let judged = check(tri, &cam);
    assert!(judged > (W * H) as usize / 2);
}

#[test]
fn two_vertices_behind_the_eye() {
    let cam = camera(0.5, 100.0);
    let tri = [Vec3::new(-1.0, -0.5, -3.0), Vec3::new(1.5, -0.7, 2.0), Vec3::new(0.2, 0.9, 1.0)];
    // Most pixels are judged, and some of them are covered (403 of 3,072 when written).
    let covered = render(&scene_of(tri), &cam, true).ids.iter().filter(|&&i| i == 1).count();
    assert!(check(tri, &cam) > (W * H) as usize / 2 && covered > 100, "{covered} covered");
}

#[test]
fn all_vertices_outside_but_covering_the_screen() {
    let cam = camera(0.5, 100.0);
    let tri = [Vec3::new(-100.0, -80.0, -5.0), Vec3::new(100.0, -90.0, -6.0), Vec3::new(3.0, 120.0, -5.5)];
    let scene = scene_of(tri);
    let fb = render(&scene, &cam, true);
    assert!(fb.ids.iter().all(|&i| i == 1), "every pixel is covered");
    check(tri, &cam);
}

#[test]
fn crossing_near_and_far_planes() {
    let cam = camera(1.0, 10.0);
    let tri = [Vec3::new(-2.0, -1.0, 3.0), Vec3::new(2.0, -1.0, -30.0), Vec3::new(0.0, 1.5, -4.0)];
    // Most pixels are judged, and some of them are covered (953 of 3,072 when written).
    let covered = render(&scene_of(tri), &cam, true).ids.iter().filter(|&&i| i == 1).count();
    assert!(check(tri, &cam) > (W * H) as usize / 2 && covered > 200, "{covered} covered");
}

#[test]
fn triangle_exactly_on_the_near_plane() {
    // near = 1, far = 3 and an identity view make clip z = −w exactly (all values are
    // binary-exact), so the triangle lies on the plane and is inside (−w ≤ z).
    let cam = camera(1.0, 3.0);
    let z = -1.0;
    let tri = [Vec3::new(-0.3, -0.4, z), Vec3::new(0.45, -0.2, z), Vec3::new(0.0, 0.5, z)];
    let m = cam.clip_from_world();
    for v in tri {
        let c = m * v.extend(1.0);
        assert_eq!(c.z, -c.w, "test setup: the vertex must lie on the near plane");
    }
    let judged = check(tri, &cam);
    let fb = render(&scene_of(tri), &cam, true);
    let covered = fb.ids.iter().filter(|&&i| i == 1).count();
    assert!(covered > 100 && judged > 1000, "{covered} covered");
    // Depth of the near plane is 0.
    assert!(fb.ids.iter().zip(&fb.depth).all(|(&i, &d)| i == 0 || d == 0.0));
}

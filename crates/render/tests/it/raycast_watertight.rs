//! The ray caster has no pinholes: rays through the shared edges and vertices of a closed
//! surface far from the eye (several hundred times a triangle's size, as across the city)
//! always hit it, through the packet renderer on every SIMD level and through the
//! single-ray queries, with the surface placed by an instance transform or not.

use glam::{Affine3A, Quat, Vec3};
use sightline_render::raycast::SimdLevel;
use sightline_render::{Framebuffer, RayCaster, RaycastOptions};
use sightline_scene::rng::Rng;
use sightline_scene::{Angle, Camera, LookAt, Mesh, NodeDesc, Scene};

use crate::support::{assert_bit_identical, pixel_ndc};

const W: u32 = 96;
const H: u32 = 64;

/// A scene of one mesh given in world space, drawn by one node with `world_from_local`.
fn placed(name: &str, world: &[Vec3], indices: Vec<u32>, world_from_local: Affine3A) -> Scene {
    let local_from_world = world_from_local.inverse();
    let positions = world.iter().map(|&p| local_from_world.transform_point3(p)).collect();
    let mut scene = Scene::new();
    let m = scene.add_mesh(Mesh::new(name, positions, None, None, indices).unwrap());
    scene.add_node(None, NodeDesc::new(name).matrix(world_from_local).mesh(m)).unwrap();
    scene.update_transforms();
    scene
}

/// Flips the triangles of `idx` that do not face `eye` (counter-clockwise as seen).
fn face(p: &[Vec3], idx: &mut [u32], eye: Vec3) {
    for t in idx.chunks_mut(3) {
        let [a, b, c] = [0, 1, 2].map(|k| p[t[k] as usize]);
        if (b - a).cross(c - a).dot(eye - a) < 0.0 {
            t.swap(1, 2);
        }
    }
}

/// A bumpy roof about 350 units from the camera whose vertices lie on pixel-center rays:
/// corners of 4 × 4-pixel cells (eight triangles meet there) and cell centers (four meet),
/// so whole rows, columns and diagonals of pixel rays run along shared edges and through
/// shared vertices. It reaches past the image on every side.
fn roof_under_the_pixels(cam: &Camera) -> (Vec<Vec3>, Vec<u32>) {
    let mut rng = Rng::new(21);
    let mut p = Vec::new();
    // The vertex on the ray of pixel (x, y) (outside the image too), at a random depth.
    let mut at = |x: i32, y: i32, rng: &mut Rng| {
        let step = glam::Vec2::new(x as f32, -y as f32) * 2.0 / glam::Vec2::new(W as f32, H as f32);
        let (o, d) = cam.ray_through_ndc(pixel_ndc(0, 0, W, H) + step);
        p.push(o + d * (350.0 / d.length()) * rng.range(0.97, 1.03));
        p.len() as u32 - 1
    };
    let (nx, ny) = (W as i32 / 4 + 4, H as i32 / 4 + 4);
    let corner: Vec<Vec<u32>> =
        (0..=ny).map(|j| (0..=nx).map(|i| at(4 * i - 8, 4 * j - 8, &mut rng)).collect()).collect();
    let mut idx = Vec::new();
    for j in 0..ny as usize {
        for i in 0..nx as usize {
            let c = at(4 * i as i32 - 6, 4 * j as i32 - 6, &mut rng);
            let ring = [corner[j][i], corner[j][i + 1], corner[j + 1][i + 1], corner[j + 1][i]];
            for k in 0..4 {
                idx.extend_from_slice(&[c, ring[k], ring[(k + 1) % 4]]);
            }
        }
    }
    face(&p, &mut idx, cam.view.eye);
    (p, idx)
}

/// Every pixel of the roof's frame is hit, with and without shadows, and the frame is the
/// same bit for bit on every SIMD level.
#[test]
fn raycast_roof_under_the_pixel_rays_has_no_pinholes() {
    let eye = Vec3::new(173.3, 137.0, -91.7);
    let look = LookAt {
        eye,
        target: eye + Vec3::new(-0.4, -0.5, 1.0),
        up: Vec3::Y,
        fovy: Angle::degrees(40.0),
        near: 1.0,
        far: 2000.0,
    };
    let cam = Camera::perspective(&look, W as f32 / H as f32).unwrap();
    let (p, idx) = roof_under_the_pixels(&cam);
    let placements = [
        Affine3A::IDENTITY,
        Affine3A::from_rotation_translation(
            Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.3, 0.2),
            Vec3::new(-61.3, 12.9, 402.1),
        ),
    ];
    for (k, m) in placements.into_iter().enumerate() {
        let scene = placed("roof", &p, idx.clone(), m);
        let caster = RayCaster::build(&scene).unwrap();
        for shadows in [false, true] {
            let mut frames = Vec::new();
            for simd in SimdLevel::all_available() {
                let mut fb = Framebuffer::new(W, H).unwrap();
                caster
                    .render(&scene, &cam, &mut fb, &RaycastOptions { shadows, simd, ..RaycastOptions::default() })
                    .unwrap();
                let holes = fb.ids.iter().filter(|&&id| id == 0).count();
                assert_eq!(holes, 0, "placement {k}, shadows {shadows}, {simd:?}: {holes} pinholes");
                frames.push(fb);
            }
            for f in &frames[1..] {
                assert_bit_identical(&frames[0], f, &format!("placement {k}, shadows {shadows}"));
            }
        }
    }
}

/// A closed icosphere (every vertex shared by five or six triangles), radius `r`, with
/// `levels` subdivisions; faces counter-clockwise seen from outside.
fn icosphere(r: f32, levels: u32) -> (Vec<Vec3>, Vec<u32>) {
    let g = (1.0 + 5f32.sqrt()) / 2.0;
    let mut p: Vec<Vec3> = [
        [-1.0, g, 0.0],
        [1.0, g, 0.0],
        [-1.0, -g, 0.0],
        [1.0, -g, 0.0],
        [0.0, -1.0, g],
        [0.0, 1.0, g],
        [0.0, -1.0, -g],
        [0.0, 1.0, -g],
        [g, 0.0, -1.0],
        [g, 0.0, 1.0],
        [-g, 0.0, -1.0],
        [-g, 0.0, 1.0],
    ]
    .iter()
    .map(|v| Vec3::from_array(*v).normalize())
    .collect();
    let mut idx: Vec<u32> = vec![
        0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4, 11, 10, 2, 10, 7, 6, 7, 1, 8, 3, 9, 4, 3,
        4, 2, 3, 2, 6, 3, 6, 8, 3, 8, 9, 4, 9, 5, 2, 4, 11, 6, 2, 10, 8, 6, 7, 9, 8, 1,
    ];
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::new();
        for t in idx.chunks(3) {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                m[k] = *mid.entry((a, b)).or_insert_with(|| {
                    p.push((p[a as usize] + p[b as usize]).normalize());
                    p.len() as u32 - 1
                });
            }
            next.extend_from_slice(&[t[0], m[0], m[2], t[1], m[1], m[0], t[2], m[2], m[1], m[0], m[1], m[2]]);
        }
        idx = next;
    }
    for v in &mut p {
        *v *= r;
    }
    for t in idx.chunks_mut(3) {
        let [a, b, c] = [0, 1, 2].map(|k| p[t[k] as usize]);
        if (b - a).cross(c - a).dot(a + b + c) < 0.0 {
            t.swap(1, 2);
        }
    }
    (p, idx)
}

/// Single rays from far away at the vertices and edge points of a closed icosphere that face
/// them: `intersect` finds the surface by the target (t ≤ 1), and `occluded` sees it.
#[test]
fn raycast_queries_at_shared_vertices_and_edges_of_a_closed_mesh_hit() {
    let (p, idx) = icosphere(3.0, 3);
    let center = Vec3::new(251.7, -118.3, 377.9);
    let m = Affine3A::from_rotation_translation(Quat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.4), center);
    let world: Vec<Vec3> = p.iter().map(|&v| m.transform_point3(v)).collect();
    let scene = placed("ball", &world, idx.clone(), m);
    let caster = RayCaster::build(&scene).unwrap();
    let mut rng = Rng::new(3);
    let (mut cast, mut slipped, mut lit) = (0, 0, 0);
    while cast < 20_000 {
        let dir = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize_or_zero();
        let o = center + dir * rng.range(300.0, 600.0);
        for _ in 0..50 {
            let t = rng.below(idx.len() as u32 / 3) as usize * 3;
            let (a, b) = (world[idx[t] as usize], world[idx[t + 1] as usize]);
            let target = if rng.below(2) == 0 { a } else { a.lerp(b, rng.f32()) };
            if (target - center).normalize().dot(dir) < 0.4 {
                continue;
            }
            cast += 1;
            let d = target - o;
            slipped += caster.intersect(o, d, 0.0, f32::INFINITY).is_none_or(|h| h.t > 1.0 + 1e-4) as usize;
            lit += !caster.occluded(o, d, 0.0, 1.0 + 1e-4) as usize;
        }
    }
    assert_eq!((slipped, lit), (0, 0), "of {cast} rays, {slipped} missed the surface and {lit} saw through it");
}

//! The ray caster against a brute-force reference: every pixel's ray tested against every
//! triangle with Möller & Trumbore's algorithm in f64, nearest hit between the near and far
//! planes (by view depth). IDs must agree on ≥ 99.9% of the pixels (the rest lie within
//! float error of an edge) and depths within 1e-5 wherever they agree.

use glam::{DMat4, DVec2, DVec4, Quat, Vec3};
use sightline_render::{Framebuffer, RayCaster, RaycastOptions};
use sightline_scene::builders::{city, CityParams};
use sightline_scene::{Angle, Camera, LookAt, Mesh, NodeDesc, Projection, Scene, Transform, View};

const W: u32 = 96;
const H: u32 = 64;

/// (ids, window depths) of the brute-force reference.
fn reference(scene: &Scene, cam: &Camera, cull: bool) -> (Vec<u32>, Vec<f64>) {
    let mut tris = Vec::new();
    for inst in scene.instances() {
        let m = scene.mesh(inst.mesh).unwrap();
        let a: DMat4 = glam::Mat4::from(inst.world_from_local).as_dmat4();
        for t in 0..m.triangle_count() {
            let p = m.triangle_positions(t).map(|v| a.transform_point3(v.as_dvec3()));
            tris.push((p, inst.first_triangle + t as u32 + 1));
        }
    }
    let clip = cam.clip_from_world_f64();
    let (u, v, w) = (cam.view.u.as_dvec3(), cam.view.v.as_dvec3(), cam.view.w.as_dvec3());
    let eye = cam.view.eye.as_dvec3();
    let (near, far) = (cam.projection.near() as f64, cam.projection.far() as f64);
    let mut ids = vec![0; (W * H) as usize];
    let mut depth = vec![1.0; (W * H) as usize];
    for r in 0..H {
        for c in 0..W {
            let ndc = DVec2::new(2.0 * (c as f64 + 0.5) / W as f64 - 1.0, 1.0 - 2.0 * (r as f64 + 0.5) / H as f64);
            let (o, d) = cam.projection.view_ray(ndc);
            let o = eye + u * o.x + v * o.y + w * o.z;
            let d = u * d.x + v * d.y + w * d.z;
            let g = -w;
            let t0 = (near - g.dot(o - eye)) / g.dot(d);
            let t1 = (far - g.dot(o - eye)) / g.dot(d);
            let mut best = (f64::INFINITY, 0u32);
            for (p, id) in &tris {
                let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
                let pv = d.cross(e2);
                let det = e1.dot(pv);
                // det = −d·(e1 × e2): positive for front faces (counter-clockwise as seen).
                if det == 0.0 || (cull && det < 0.0) {
                    continue;
                }
                let s = o - p[0];
                let bu = s.dot(pv) / det;
                let q = s.cross(e1);
                let bv = d.dot(q) / det;
                if bu < 0.0 || bv < 0.0 || bu + bv > 1.0 {
                    continue;
                }
                let t = e2.dot(q) / det;
                if t >= t0 && t <= t1 && t < best.0 {
                    best = (t, *id);
                }
            }
            let i = (r * W + c) as usize;
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

fn check(name: &str, scene: &Scene, cam: &Camera, cull: bool) {
    let caster = RayCaster::build(scene).unwrap();
    let mut fb = Framebuffer::new(W, H).unwrap();
    let opts = RaycastOptions { backface_culling: cull, ..RaycastOptions::ids_only() };
    caster.render(scene, cam, &mut fb, &opts).unwrap();
    let (ids, depth) = reference(scene, cam, cull);
    let same = ids.iter().zip(&fb.ids).filter(|(a, b)| a == b).count();
    let mut worst = 0f64;
    for i in 0..ids.len() {
        if ids[i] != 0 && ids[i] == fb.ids[i] {
            worst = worst.max((depth[i] - fb.depth[i] as f64).abs());
        }
    }
    let hits = ids.iter().filter(|&&i| i != 0).count();
    let agree = same as f64 / ids.len() as f64;
    eprintln!("{name}: {:.3}% of IDs agree, max depth diff {worst:e}, {hits} hit pixels", agree * 100.0);
    assert!(hits > 0, "{name}: nothing visible");
    assert!(agree >= 0.999, "{name}: {:.3}% of IDs agree", agree * 100.0);
    assert!(worst <= 1e-5, "{name}: depth differs by {worst}");
}

#[test]
fn raycast_matches_brute_force_on_a_city() {
    let c = city(&CityParams::for_triangles(8_000)).unwrap();
    let aspect = W as f32 / H as f32;
    let street = c.layout.street_path(10, 5);
    let aerial = c.layout.aerial_path(4);
    check("street", &c.scene, &street[2].camera(aspect).unwrap(), true);
    check("aerial", &c.scene, &aerial[1].camera(aspect).unwrap(), true);
    check("aerial, both sides", &c.scene, &aerial[2].camera(aspect).unwrap(), false);
    let b = c.layout.bounds();
    let view = View::look_at(b.center() + Vec3::new(80.0, 120.0, 60.0), b.center(), Vec3::Y).unwrap();
    let r = b.extent().length() * 0.4;
    let ortho = Projection::orthographic(-r, r, -r / aspect, r / aspect, 1.0, 800.0).unwrap();
    let obl = Projection::cavalier(-r, r, -r / aspect, r / aspect, 1.0, 800.0, 0.7).unwrap();
    check("orthographic", &c.scene, &Camera::new(view, ortho).unwrap(), true);
    check("cavalier", &c.scene, &Camera::new(view, obl).unwrap(), true);
}

#[test]
fn raycast_matches_brute_force_on_transformed_instances() {
    // Rotated, non-uniformly scaled and mirrored instances of one mesh, plus a flattened
    // (zero-scale) one that cannot be inverted.
    let mut scene = Scene::new();
    let m = scene
        .add_mesh(sightline_scene::shapes::subdivided_box("b", Vec3::splat(-1.0), Vec3::ONE, [3, 2, 1], true).unwrap());
    let ts = [
        Transform::from_translation(Vec3::new(-2.5, 0.0, 0.0)).with_rotation(Quat::from_rotation_y(0.6)),
        Transform::from_translation(Vec3::new(0.0, 0.5, -1.0)).with_scale(Vec3::new(0.5, 2.0, 1.0)),
        Transform::from_translation(Vec3::new(2.5, 0.0, 0.0)).with_scale(Vec3::new(-1.0, 1.0, 1.0)),
        Transform::from_translation(Vec3::new(0.0, -2.0, 0.0)).with_scale(Vec3::new(3.0, 0.0, 3.0)),
    ];
    for (k, t) in ts.into_iter().enumerate() {
        scene.add_node(None, NodeDesc::new(format!("i{k}")).transform(t).mesh(m)).unwrap();
    }
    let shard = Mesh::new(
        "shard",
        vec![Vec3::new(-3.0, -1.0, 1.0), Vec3::new(3.0, -1.5, 0.5), Vec3::new(0.0, 2.5, -2.0)],
        None,
        None,
        vec![0, 1, 2],
    )
    .unwrap();
    let s = scene.add_mesh(shard);
    scene.add_node(None, NodeDesc::new("shard").mesh(s)).unwrap();
    scene.update_transforms();
    let aspect = W as f32 / H as f32;
    for (k, eye) in [Vec3::new(1.0, 4.0, 9.0), Vec3::new(-6.0, -3.0, 5.0), Vec3::new(0.5, 9.0, 0.3)].iter().enumerate()
    {
        let cam = Camera::perspective(
            &LookAt { eye: *eye, target: Vec3::ZERO, up: Vec3::Y, fovy: Angle::degrees(55.0), near: 0.5, far: 40.0 },
            aspect,
        )
        .unwrap();
        check(&format!("instances {k}"), &scene, &cam, true);
        check(&format!("instances {k}, both sides"), &scene, &cam, false);
    }
}

/// A single ray names the triangle it hits by its mesh index, whatever order the BVH keeps
/// the triangles in: separate triangles listed in a scrambled order, in two instances, each
/// hit at its centroid, give that instance, that mesh index, its ID and barycentric weights
/// of a third.
#[test]
fn a_single_ray_names_the_mesh_triangle_it_hits() {
    let (side, n) = (12usize, 144usize);
    let mut positions = Vec::new();
    let mut centroids = vec![Vec3::ZERO; n];
    let mut indices = vec![0u32; 3 * n];
    for k in 0..n {
        // Mesh triangle k sits at cell (k·37) mod n, so mesh order is not spatial order.
        let cell = (k * 37) % n;
        let o = Vec3::new((cell % side) as f32 * 2.0, (cell / side) as f32 * 2.0, 0.0);
        let first = positions.len() as u32;
        positions.extend([o, o + Vec3::X, o + Vec3::Y]);
        indices[3 * k..3 * k + 3].copy_from_slice(&[first, first + 1, first + 2]);
        centroids[k] = o + Vec3::new(1.0, 1.0, 0.0) / 3.0;
    }
    let mut scene = Scene::new();
    let m = scene.add_mesh(Mesh::new("scrambled", positions, None, None, indices).unwrap());
    let shift = Vec3::new(0.0, 0.0, -10.0);
    scene.add_node(None, NodeDesc::new("a").mesh(m)).unwrap();
    scene.add_node(None, NodeDesc::new("b").transform(Transform::from_translation(shift)).mesh(m)).unwrap();
    scene.update_transforms();
    let caster = RayCaster::build(&scene).unwrap();
    let instances = scene.instances();
    for (i, inst) in instances.iter().enumerate() {
        let moved = if inst.world_from_local.translation.z < 0.0 { shift } else { Vec3::ZERO };
        for (k, c) in centroids.iter().enumerate() {
            // From below: the ray meets instance b first only when it is b's turn.
            let (o, d) =
                if moved == Vec3::ZERO { (*c + Vec3::Z, Vec3::NEG_Z) } else { (*c + moved - Vec3::Z, Vec3::Z) };
            let hit = caster.intersect(o, d, 0.0, f32::INFINITY).expect("the centroid is hit");
            let sightline_render::raycast::HitTarget::Triangle { instance, triangle, barycentric } = hit.target else {
                panic!("a mesh triangle is hit")
            };
            assert_eq!((instance, triangle), (i, k as u32), "instance {i}, triangle {k}");
            assert_eq!(hit.id, sightline_render::triangle_id(inst.first_triangle, k as u32));
            assert!((barycentric - glam::Vec2::splat(1.0 / 3.0)).abs().max_element() < 1e-5, "{barycentric}");
        }
    }
}

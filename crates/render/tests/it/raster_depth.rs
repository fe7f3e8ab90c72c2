//! Depth precision: two parallel quads 1e-4 apart at distance 50 z-fight (mixed IDs) with a
//! 16-bit depth buffer and do not with f32 (nor with 24 bits at this near/far ratio).

use glam::{Affine3A, Quat, Vec3};
use sightline_render::{render_scene, DepthFormat, Framebuffer, RenderOptions};
use sightline_scene::{Angle, Camera, LookAt, Mesh, NodeDesc, Scene};

fn scene() -> Scene {
    let mut s = Scene::new();
    let p = vec![
        Vec3::new(-10.0, -10.0, 0.0),
        Vec3::new(10.0, -10.0, 0.0),
        Vec3::new(10.0, 10.0, 0.0),
        Vec3::new(-10.0, 10.0, 0.0),
    ];
    let m = s.add_mesh(Mesh::new("quad", p, None, None, vec![0, 1, 2, 0, 2, 3]).unwrap());
    let rot = Quat::from_rotation_x(30f32.to_radians());
    let normal = rot * Vec3::Z; // towards the camera
    let center = Vec3::new(0.0, 0.0, -50.0);
    // The far quad is drawn first (IDs 1, 2), the near one 1e-4 closer (IDs 3, 4).
    for (name, offset) in [("far", 0.0), ("near", 1e-4)] {
        let t = Affine3A::from_rotation_translation(rot, center + normal * offset);
        s.add_node(None, NodeDesc::new(name).matrix(t).mesh(m)).unwrap();
    }
    s.update_transforms();
    s
}

/// (pixels showing the far quad, pixels showing the near quad).
fn fight(format: DepthFormat) -> (usize, usize) {
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::ZERO,
            target: Vec3::NEG_Z,
            up: Vec3::Y,
            fovy: Angle::degrees(30.0),
            near: 20.0,
            far: 200.0,
        },
        4.0 / 3.0,
    )
    .unwrap();
    let mut fb = Framebuffer::new(128, 96).unwrap();
    let opts = RenderOptions { depth_format: format, ..RenderOptions::ids_only() };
    render_scene(&scene(), &cam, &mut fb, &opts).unwrap();
    let far = fb.ids.iter().filter(|&&i| i == 1 || i == 2).count();
    let near = fb.ids.iter().filter(|&&i| i == 3 || i == 4).count();
    (far, near)
}

#[test]
fn sixteen_bit_depth_fights_and_f32_does_not() {
    let (far, near) = fight(DepthFormat::Unorm16);
    let covered = far + near;
    assert!(covered > 3000, "{covered}");
    assert!(far * 100 > covered && near * 100 > covered, "16-bit: far {far}, near {near}: no fighting");
    for f in [DepthFormat::F32, DepthFormat::Unorm24] {
        let (far, near) = fight(f);
        assert!(far * 1000 < near, "{f:?}: far {far}, near {near}: the nearer quad must win");
    }
}

//! Perspective-correct interpolation: a textured ground quad seen at a grazing angle matches
//! an analytic per-pixel ray–plane reference within one texel; affine (screen-space)
//! interpolation of the same attributes measurably does not.

use std::sync::Arc;

use glam::{Vec2, Vec3};
use sightline_render::texture::{Filter, Wrap};
use sightline_render::{render_scene, Framebuffer, RenderOptions, ShadeOptions};
use sightline_scene::{Angle, Camera, LookAt, Material, Mesh, NodeDesc, Scene, Texture};

use crate::support::pixel_ndc;

const N: u32 = 64; // texels per side
const W: u32 = 128;
const H: u32 = 96;

/// Texel (i, j) stores i and j in red and green (×4) and a checkerboard in blue.
fn coded_checkerboard() -> Texture {
    let mut rgba = Vec::new();
    for j in 0..N {
        for i in 0..N {
            rgba.extend_from_slice(&[(i * 4) as u8, (j * 4) as u8, (((i + j) % 2) * 255) as u8, 255]);
        }
    }
    Texture::new(N, N, rgba).unwrap()
}

fn scene() -> Scene {
    let mut s = Scene::new();
    let (x0, x1, z0, z1) = (-5.0, 5.0, -1.0, -61.0);
    let positions =
        vec![Vec3::new(x0, 0.0, z0), Vec3::new(x1, 0.0, z0), Vec3::new(x1, 0.0, z1), Vec3::new(x0, 0.0, z1)];
    let uvs = vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)];
    let mesh = Mesh::new("ground", positions, Some(vec![Vec3::Y; 4]), Some(uvs), vec![0, 1, 2, 0, 2, 3]).unwrap();
    let m = s.add_mesh(mesh);
    let mat = s.add_material(Material {
        name: "checker".into(),
        base_color: [1.0; 4],
        base_color_texture: Some(Arc::new(coded_checkerboard())),
        ..Material::default()
    });
    s.add_node(None, NodeDesc::new("ground").mesh(m).material(mat)).unwrap();
    s.update_transforms();
    s
}

/// Largest texel error over pixels whose reference hit lies well inside the quad.
fn max_texel_error(perspective_correct: bool) -> (i32, usize) {
    let scene = scene();
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 1.0, 0.0),
            target: Vec3::new(0.0, 0.75, -10.0),
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 200.0,
        },
        W as f32 / H as f32,
    )
    .unwrap();
    let mut fb = Framebuffer::new(W, H).unwrap();
    let opts = RenderOptions {
        backface_culling: false,
        shading: ShadeOptions {
            filter: Filter::Nearest,
            wrap: Wrap::Clamp,
            perspective_correct,
            ..ShadeOptions::unlit()
        },
        ..RenderOptions::default()
    };
    render_scene(&scene, &cam, &mut fb, &opts).unwrap();
    let (mut worst, mut judged) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let (o, d) = cam.ray_through_ndc(pixel_ndc(x, y, W, H));
            let (o, d) = (o.as_dvec3(), d.as_dvec3());
            if d.y >= 0.0 {
                continue;
            }
            let p = o + d * (-o.y / d.y);
            let u = (p.x + 5.0) / 10.0;
            let v = (-1.0 - p.z) / 60.0;
            if !(0.01..0.99).contains(&u) || !(0.01..0.99).contains(&v) {
                continue;
            }
            let i = fb.index(x, y);
            assert_ne!(fb.ids[i], 0, "pixel ({x},{y}) sees the quad");
            let c = fb.color[i];
            let (ti, tj) = (c[0] as i32 / 4, c[1] as i32 / 4);
            let (ri, rj) = ((u * N as f64).floor() as i32, (v * N as f64).floor() as i32);
            worst = worst.max((ti - ri).abs()).max((tj - rj).abs());
            judged += 1;
        }
    }
    (worst, judged)
}

#[test]
fn perspective_correct_texturing_matches_ray_plane_reference() {
    let (worst, judged) = max_texel_error(true);
    assert!(judged > (W * H / 3) as usize, "{judged} pixels judged");
    assert!(worst <= 1, "perspective-correct texturing is {worst} texels off");
}

#[test]
fn affine_interpolation_measurably_fails() {
    let (worst, _) = max_texel_error(false);
    assert!(worst >= 4, "affine interpolation is only {worst} texels off: the test is too weak");
}

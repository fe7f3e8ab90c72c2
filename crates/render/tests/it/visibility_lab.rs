//! The lab's object-order methods against the z-buffer: painter's with the
//! Newell–Newell–Sancha tests and BSP rendering (back to front, front to back) give the
//! rasterizer's triangle IDs on ≥ 99.9% of the pixels of scenes built to break a plain depth
//! sort (interpenetrating triangles, three sticks overlapping in a cycle, random crossing
//! soups, a small city), differing only where a boundary between two triangles moved by a
//! pixel; the centroid sort gets the cycle wrong.

use glam::Vec3;
use sightline_render::visibility::{bsp, painter, BspMode, BspRenderer, Counters, Soup};
use sightline_render::{render_scene, Framebuffer, RenderOptions};
use sightline_scene::builders::{city, CityParams};
use sightline_scene::rng::Rng;
use sightline_scene::{Angle, Camera, LookAt, Mesh, Projection, View};

use crate::support::one_node_scene;

const W: u32 = 256;
const H: u32 = 192;

/// The soup as one mesh under the identity transform: what the z-buffer draws.
fn zbuffer(soup: &Soup, camera: &Camera) -> Vec<u32> {
    let positions: Vec<Vec3> = soup.triangles().iter().flatten().copied().collect();
    let indices = (0..positions.len() as u32).collect();
    let scene = one_node_scene("soup", Mesh::new("soup", positions, None, None, indices).unwrap());
    let mut fb = Framebuffer::new(W, H).unwrap();
    render_scene(&scene, camera, &mut fb, &RenderOptions::ids_only()).unwrap();
    fb.ids.into()
}

fn camera(eye: Vec3, target: Vec3) -> Camera {
    let look = LookAt { eye, target, up: Vec3::Y, fovy: Angle::degrees(45.0), near: 0.5, far: 100.0 };
    Camera::perspective(&look, W as f32 / H as f32).unwrap()
}

/// Pixels whose ID differs, and how many of those are not on a boundary: a differing pixel
/// is on a boundary when each image's ID there shows up in the other image within one pixel
/// (the line between the two triangles moved by at most a pixel).
fn differences(got: &[u32], want: &[u32]) -> (usize, usize) {
    let (w, h) = (W as i64, H as i64);
    let near = |img: &[u32], x: i64, y: i64, id: u32| {
        (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                let (nx, ny) = (x + dx, y + dy);
                nx >= 0 && ny >= 0 && nx < w && ny < h && img[(ny * w + nx) as usize] == id
            })
        })
    };
    let (mut diff, mut off) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if got[i] != want[i] {
                diff += 1;
                if !(near(want, x, y, got[i]) && near(got, x, y, want[i])) {
                    off += 1;
                }
            }
        }
    }
    (diff, off)
}

/// Checks one method's image against the z-buffer's and returns the agreement in percent.
fn check(scene: &str, method: &str, fb: &Framebuffer, want: &[u32], counters: &Counters) -> f64 {
    let (diff, off) = differences(&fb.ids, want);
    let pct = 100.0 * (1.0 - diff as f64 / want.len() as f64);
    println!("{scene}: {method} differs on {diff} pixels ({pct:.3}% agree), {off} off boundaries; {counters:?}");
    assert!(diff * 1000 <= want.len(), "{scene}: {method} differs on {diff} of {} pixels", want.len());
    assert_eq!(off, 0, "{scene}: {method} differs away from boundaries");
    pct
}

/// Three sticks (thin quads), each lying over the next where they cross, in a cycle: no
/// order of whole sticks is right.
fn sticks(center: Vec3) -> Vec<[Vec3; 3]> {
    let (r, half_width, slope) = (1.0f32, 0.18f32, 0.25f32);
    let len = 2.0 * r * 3f32.sqrt();
    let mut tris = Vec::new();
    for k in 0..3 {
        let th = std::f32::consts::TAU * k as f32 / 3.0;
        let d = Vec3::new(th.cos(), th.sin(), 0.0);
        let n = Vec3::new(-th.sin(), th.cos(), 0.0);
        let at = |s: f32| center - n * r + d * s + Vec3::Z * (slope * s);
        let (a0, a1) = (at(-len) - n * half_width, at(-len) + n * half_width);
        let (b0, b1) = (at(len) - n * half_width, at(len) + n * half_width);
        // Counter-clockwise seen from +z: along d, then along n.
        tris.push([a0, b0, b1]);
        tris.push([a0, b1, a1]);
    }
    tris
}

/// Two triangles piercing each other and two quads crossing in an X.
fn piercing(center: Vec3) -> Vec<[Vec3; 3]> {
    let o = center;
    let v = |x: f32, y: f32, z: f32| o + Vec3::new(x, y, z);
    vec![
        [v(-1.0, -1.0, 0.0), v(1.0, -1.0, 0.0), v(0.0, 1.2, 0.0)],
        [v(-1.0, 0.0, -1.0), v(1.0, 0.2, 1.0), v(0.0, 0.9, 1.0)],
        // The X: two quads tilted about the y axis in opposite directions.
        [v(-0.9, -2.6, -0.6), v(0.9, -2.6, 0.6), v(0.9, -1.4, 0.6)],
        [v(-0.9, -2.6, -0.6), v(0.9, -1.4, 0.6), v(-0.9, -1.4, -0.6)],
        [v(-0.9, -2.6, 0.6), v(0.9, -2.6, -0.6), v(0.9, -1.4, -0.6)],
        [v(-0.9, -2.6, 0.6), v(0.9, -1.4, -0.6), v(-0.9, -1.4, 0.6)],
    ]
}

/// Random triangles in a box, most of them crossing others.
fn crossing_soup(seed: u64, n: usize) -> Vec<[Vec3; 3]> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let c = Vec3::new(rng.range(-3.0, 3.0), rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
            let mut p = || c + Vec3::new(rng.range(-1.2, 1.2), rng.range(-1.2, 1.2), rng.range(-1.2, 1.2));
            [p(), p(), p()]
        })
        .collect()
}

/// Runs painter's and both BSP walks on `tris` for each eye, against the z-buffer.
fn all_methods_agree(scene: &str, tris: Vec<[Vec3; 3]>, eyes: &[Vec3], target: Vec3) {
    let soup = Soup::from_triangles(tris);
    let tree = BspRenderer::new(&soup).unwrap();
    let mut fb = Framebuffer::new(W, H).unwrap();
    for (k, &eye) in eyes.iter().enumerate() {
        let cam = camera(eye, target);
        let want = zbuffer(&soup, &cam);
        let covered = want.iter().filter(|&&i| i != 0).count();
        assert!(covered > (W * H / 10) as usize, "{scene}: the view must show the scene ({covered} pixels)");
        let name = format!("{scene}, eye {k}");
        let c = painter::render(&soup, &cam, &mut fb).unwrap();
        check(&name, "painter", &fb, &want, &c);
        let c = tree.render(&cam, &mut fb, BspMode::BackToFront).unwrap();
        check(&name, "bsp back to front", &fb, &want, &c);
        let c = tree.render(&cam, &mut fb, BspMode::FrontToBack).unwrap();
        check(&name, "bsp front to back", &fb, &want, &c);
    }
}

#[test]
fn sticks_in_a_cycle_and_piercing_triangles() {
    let mut tris = sticks(Vec3::new(-1.5, 0.0, 0.0));
    tris.extend(piercing(Vec3::new(2.2, 0.5, 0.0)));
    let eyes = [Vec3::new(0.3, 0.2, 8.0), Vec3::new(-1.0, 1.5, 7.0), Vec3::new(2.0, -1.0, 6.5)];
    all_methods_agree("sticks + piercing", tris, &eyes, Vec3::new(0.3, 0.0, 0.0));
}

#[test]
fn random_crossing_soups() {
    for seed in [1, 2] {
        let eyes = [Vec3::new(0.5, 1.0, 6.5), Vec3::new(-4.5, 2.0, 4.5)];
        all_methods_agree(&format!("crossing soup {seed}"), crossing_soup(seed, 60), &eyes, Vec3::ZERO);
    }
}

#[test]
fn painter_splits_the_cycle_and_the_centroid_sort_gets_it_wrong() {
    let soup = Soup::from_triangles(sticks(Vec3::ZERO));
    let cam = camera(Vec3::new(0.2, 0.1, 7.0), Vec3::ZERO);
    let want = zbuffer(&soup, &cam);
    let mut fb = Framebuffer::new(W, H).unwrap();
    let c = painter::render(&soup, &cam, &mut fb).unwrap();
    assert!(c.get("splits").unwrap() >= 1, "a cycle needs a split: {c:?}");
    assert!(c.get("reorderings").unwrap() >= 1, "{c:?}");
    assert!(c.get("comparisons").unwrap() >= 6, "{c:?}");
    check("sticks", "painter", &fb, &want, &c);
    let c = painter::render_centroid_sort(&soup, &cam, &mut fb).unwrap();
    let (wrong, _) = differences(&fb.ids, &want);
    println!("sticks: centroid sort differs on {wrong} pixels; {c:?}");
    assert!(wrong > 100, "the centroid sort must get the cycle wrong ({wrong} pixels)");
    assert_eq!(c.get("triangles_sorted"), Some(6));
}

#[test]
fn bsp_orders_parallel_projections_from_the_viewer_side() {
    let mut tris = sticks(Vec3::new(-1.5, 0.0, 0.0));
    tris.extend(piercing(Vec3::new(2.2, 0.5, 0.0)));
    let soup = Soup::from_triangles(tris);
    let tree = BspRenderer::new(&soup).unwrap();
    assert!(tree.stats().splits >= 1);
    let view = View::look_at(Vec3::new(0.5, 0.8, 9.0), Vec3::new(0.3, 0.0, 0.0), Vec3::Y).unwrap();
    let ortho = Projection::orthographic(-4.0, 4.0, -3.0, 3.0, 1.0, 30.0).unwrap();
    let cam = Camera::new(view, ortho).unwrap();
    let want = zbuffer(&soup, &cam);
    let mut fb = Framebuffer::new(W, H).unwrap();
    for mode in [BspMode::BackToFront, BspMode::FrontToBack] {
        let c = tree.render(&cam, &mut fb, mode).unwrap();
        check("orthographic", &format!("bsp {mode:?}"), &fb, &want, &c);
    }
    let c = painter::render(&soup, &cam, &mut fb).unwrap();
    check("orthographic", "painter", &fb, &want, &c);
}

#[test]
fn front_to_back_writes_each_pixel_once_and_stops_when_the_screen_is_full() {
    // A wall filling the view in front of a soup: the walk ends before the soup.
    let mut tris = vec![
        [Vec3::new(-50.0, -50.0, 3.0), Vec3::new(50.0, -50.0, 3.0), Vec3::new(50.0, 50.0, 3.0)],
        [Vec3::new(-50.0, -50.0, 3.0), Vec3::new(50.0, 50.0, 3.0), Vec3::new(-50.0, 50.0, 3.0)],
    ];
    tris.extend(crossing_soup(3, 30));
    let soup = Soup::from_triangles(tris);
    let cam = camera(Vec3::new(0.0, 0.0, 9.0), Vec3::ZERO);
    let want = zbuffer(&soup, &cam);
    assert!(want.iter().all(|&i| i == 1 || i == 2));
    let mut fb = Framebuffer::new(W, H).unwrap();
    let f2b = bsp::render(&soup, &cam, &mut fb, BspMode::FrontToBack).unwrap();
    check("wall", "bsp front to back", &fb, &want, &f2b);
    assert_eq!(f2b.get("fragments_written"), Some((W * H) as u64));
    let b2f = bsp::render(&soup, &cam, &mut fb, BspMode::BackToFront).unwrap();
    check("wall", "bsp back to front", &fb, &want, &b2f);
    assert!(f2b.get("nodes_visited") < b2f.get("nodes_visited"), "{f2b:?} vs {b2f:?}");
    assert!(b2f.get("fragments_written").unwrap() > (W * H) as u64, "{b2f:?}");
}

#[test]
fn a_small_city_from_above() {
    let c = city(&CityParams::for_triangles(5_000)).unwrap();
    let soup = Soup::from_scene(&c.scene).unwrap();
    let b = c.layout.bounds();
    let (center, r) = (b.center(), b.extent().length());
    let look = LookAt {
        eye: center + Vec3::new(0.6, 0.5, 0.8).normalize() * r * 0.7,
        target: center,
        up: Vec3::Y,
        fovy: Angle::degrees(50.0),
        near: r * 0.01,
        far: r * 4.0,
    };
    let cam = Camera::perspective(&look, W as f32 / H as f32).unwrap();
    // The city drawn as the renderer draws it (instances under their own transforms).
    let mut reference = Framebuffer::new(W, H).unwrap();
    render_scene(&c.scene, &cam, &mut reference, &RenderOptions::ids_only()).unwrap();
    let mut fb = Framebuffer::new(W, H).unwrap();
    let name = format!("city of {} triangles", soup.len());
    let p = painter::render(&soup, &cam, &mut fb).unwrap();
    check(&name, "painter", &fb, &reference.ids, &p);
    let tree = BspRenderer::new(&soup).unwrap();
    let t = tree.render(&cam, &mut fb, BspMode::BackToFront).unwrap();
    check(&name, "bsp back to front", &fb, &reference.ids, &t);
    let t = tree.render(&cam, &mut fb, BspMode::FrontToBack).unwrap();
    check(&name, "bsp front to back", &fb, &reference.ids, &t);
}

#[test]
fn oversized_soups_are_refused_by_painter() {
    let soup = Soup::from_triangles(vec![[Vec3::ZERO, Vec3::X, Vec3::Y]; painter::LIMIT + 1]);
    let mut fb = Framebuffer::new(8, 8).unwrap();
    let err = painter::render(&soup, &camera(Vec3::Z * 5.0, Vec3::ZERO), &mut fb).unwrap_err().to_string();
    assert!(err.contains("painter") && err.contains(&painter::LIMIT.to_string()), "{err}");
}

/// Exact copies of a triangle tie in depth everywhere; the z-buffer keeps the smaller ID
/// (in-order drawing), and so must painter's and the BSP tree: copies listed in both orders,
/// over and under a third, larger triangle.
#[test]
fn coincident_copies_keep_the_smaller_id_as_the_z_buffer_does() {
    let a = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
    let big = [Vec3::new(-2.0, -2.0, -0.5), Vec3::new(2.0, -2.0, -0.5), Vec3::new(0.0, 2.0, -0.5)];
    let tris = vec![big, a, a, big, a];
    all_methods_agree("coincident copies", tris, &[Vec3::new(0.2, 0.1, 4.0), Vec3::new(-1.0, 0.5, 3.0)], Vec3::ZERO);
}

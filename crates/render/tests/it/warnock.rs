//! Warnock's area subdivision draws the z-buffer's triangle IDs: exactly on soups drawn
//! as they are (the same triangles set up the same way), on ≥ 99.9% of the pixels of a
//! city (whose instances the rasterizer transforms by their own matrices, rounding a vertex
//! differently now and then); interpenetrating and cyclically overlapping triangles, the
//! cases that defeat a depth sort, included. Random soups with degenerate and coplanar
//! triangles never panic and terminate within a bounded number of windows.

use glam::{Quat, Vec3};
use proptest::prelude::*;
use sightline_render::visibility::warnock::{self, Options};
use sightline_render::visibility::Soup;
use sightline_render::{render_scene, Error, Framebuffer, RenderOptions};
use sightline_scene::{Angle, Camera, LookAt, Mesh, Scene};

use crate::support::{one_node_scene, small_city};

const W: u32 = 192;
const H: u32 = 108;

/// The z-buffer's frame and Warnock's of `scene`; the share of pixels whose IDs agree.
fn agreement(scene: &Scene, camera: &Camera, cull: bool) -> (f64, Framebuffer, Framebuffer) {
    let opts = RenderOptions { backface_culling: cull, ..RenderOptions::ids_only() };
    let mut z = Framebuffer::new(W, H).unwrap();
    render_scene(scene, camera, &mut z, &opts).unwrap();
    let soup = Soup::from_scene(scene).unwrap();
    let mut a = Framebuffer::new(W, H).unwrap();
    let c = warnock::render_with(&soup, camera, &mut a, &Options { backface_culling: cull }).unwrap();
    assert_eq!(c.get("windows"), Some((0..14).filter_map(|k| c.get(&format!("windows_level_{k}"))).sum()));
    assert!(c.get("polygons_tested").unwrap() > 0);
    let same = z.ids.iter().zip(&a.ids).filter(|(x, y)| x == y).count();
    (same as f64 / z.len() as f64, z, a)
}

/// A scene of one mesh holding `tris` (identity transform, so its soup is its own mesh).
fn soup_scene(tris: &[[Vec3; 3]]) -> Scene {
    let positions: Vec<Vec3> = tris.iter().flatten().copied().collect();
    let indices = (0..positions.len() as u32).collect();
    one_node_scene("soup", Mesh::new("soup", positions, None, None, indices).unwrap())
}

fn camera(eye: Vec3) -> Camera {
    let look = LookAt { eye, target: Vec3::ZERO, up: Vec3::Y, fovy: Angle::degrees(55.0), near: 0.1, far: 60.0 };
    Camera::perspective(&look, W as f32 / H as f32).unwrap()
}

/// Large triangles piercing each other at many angles, from a fixed generator.
fn shards(n: usize, seed: u64) -> Vec<[Vec3; 3]> {
    let mut rng = seed;
    let mut next = || {
        rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((rng >> 33) as f32 / (1u64 << 31) as f32) * 2.0 - 1.0
    };
    (0..n)
        .map(|_| {
            let c = Vec3::new(next(), next(), next()) * 2.0;
            [(); 3].map(|_| c + Vec3::new(next(), next(), next()) * 2.5)
        })
        .collect()
}

/// Three sticks each lying over the next at one crossing and under it at the other (no
/// order of whole triangles is right), and two triangles piercing each other.
fn cycle() -> Vec<[Vec3; 3]> {
    let mut tris = Vec::new();
    let len = 2.0 * 3f32.sqrt();
    for k in 0..3 {
        let th = std::f32::consts::TAU * k as f32 / 3.0;
        let (d, n) = (Vec3::new(th.cos(), th.sin(), 0.0), Vec3::new(-th.sin(), th.cos(), 0.0));
        let at = |s: f32| -n + d * s + Vec3::Z * (0.25 * s);
        tris.push([at(-len) - n, at(-len) + n, at(len)]);
    }
    let o = Vec3::new(3.5, 0.0, 0.0);
    tris.push([o + Vec3::new(-1.0, -1.0, 0.0), o + Vec3::new(1.0, -1.0, 0.0), o + Vec3::new(0.0, 1.2, 0.0)]);
    tris.push([o + Vec3::new(-1.0, 0.0, -1.0), o + Vec3::new(1.0, 0.2, 1.0), o + Vec3::new(0.0, 0.9, 1.0)]);
    tris
}

fn assert_same_frame(z: &Framebuffer, a: &Framebuffer, what: &str) {
    let differ = z.ids.iter().zip(&a.ids).filter(|(x, y)| x != y).count();
    assert_eq!(differ, 0, "{what}: {differ} pixels differ from the z-buffer");
    let bits = |f: &Framebuffer| f.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
    assert!(bits(z) == bits(a), "{what}: depths differ from the z-buffer");
}

#[test]
fn warnock_equals_the_z_buffer_on_interpenetrating_and_cyclic_triangles() {
    let scenes = [("shards", shards(80, 7)), ("more shards", shards(200, 99)), ("cycle", cycle())];
    for (name, tris) in &scenes {
        let scene = soup_scene(tris);
        for (k, eye) in
            [Vec3::new(0.0, 1.0, 9.0), Vec3::new(7.0, -3.0, 4.0), Vec3::new(0.5, 0.2, -6.0)].iter().enumerate()
        {
            for cull in [false, true] {
                let (share, z, a) = agreement(&scene, &camera(*eye), cull);
                let what = format!("{name}, camera {k}, culling {cull}");
                assert!(z.ids.iter().any(|&i| i != 0), "{what}: nothing visible, the test proves nothing");
                assert!(share >= 0.999, "{what}: {:.3}% agree", share * 100.0);
                assert_same_frame(&z, &a, &what);
            }
        }
    }
}

#[test]
fn warnock_agrees_with_the_z_buffer_on_a_city() {
    let c = small_city();
    let aspect = W as f32 / H as f32;
    let street = c.layout.street_path(40, 3);
    let aerial = c.layout.aerial_path(12);
    for (k, key) in [street[0], street[21], aerial[0], aerial[7]].iter().enumerate() {
        let (share, z, _) = agreement(&c.scene, &key.camera(aspect).unwrap(), true);
        eprintln!("city camera {k}: Warnock agrees with the z-buffer on {:.4}% of the pixels", share * 100.0);
        assert!(z.ids.iter().filter(|&&i| i != 0).count() > z.len() / 4, "city camera {k}: too little visible");
        assert!(share >= 0.999, "city camera {k}: only {:.3}% agree", share * 100.0);
    }
}

#[test]
fn warnock_refuses_a_soup_over_its_limit_by_name() {
    let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let soup = Soup::from_triangles(vec![tri; warnock::MAX_TRIANGLES + 1]);
    let mut fb = Framebuffer::new(8, 8).unwrap();
    let err = warnock::render(&soup, &camera(Vec3::Z * 5.0), &mut fb).unwrap_err();
    assert!(matches!(err, Error::TooLarge { method: "warnock", .. }), "{err}");
    assert!(err.to_string().contains(&warnock::MAX_TRIANGLES.to_string()), "{err}");
}

/// A random small soup: triangles in a box, some degenerate (repeated or collinear
/// vertices), some copies of others (coplanar and coincident), some sharing a plane.
fn soup_strategy() -> impl Strategy<Value = Vec<[Vec3; 3]>> {
    let v = prop::array::uniform3(-3.0f32..3.0).prop_map(Vec3::from);
    let tri = (prop::array::uniform3(v), 0u8..6).prop_map(|([a, b, c], kind)| match kind {
        0 => [a, a, b],                                                          // two vertices the same
        1 => [a, b, a + (b - a) * 0.37],                                         // collinear
        2 => [a, b, Vec3::new(c.x, c.y, a.z)].map(|p| Vec3::new(p.x, p.y, 0.5)), // on the plane z = 0.5
        _ => [a, b, c],
    });
    prop::collection::vec(tri, 0..40).prop_flat_map(|tris| {
        let n = tris.len();
        // Duplicate some triangles (coincident ones, ties in depth everywhere).
        (Just(tris), prop::collection::vec(0..n.max(1), 0..6)).prop_map(move |(mut tris, dups)| {
            for d in dups {
                if let Some(&t) = tris.get(d) {
                    tris.push(t);
                }
            }
            tris
        })
    })
}

proptest! {
    // Each case in a subprocess with a time bound: an endless subdivision fails the case.
    #![proptest_config(ProptestConfig { cases: 48, timeout: 20_000, ..ProptestConfig::default() })]

    #[test]
    fn warnock_never_panics_and_terminates_on_random_soups(
        tris in soup_strategy(),
        eye in prop::array::uniform3(-8.0f32..8.0),
        turn in 0.0f32..std::f32::consts::TAU,
        (w, h) in (1u32..48, 1u32..40),
        cull in any::<bool>(),
    ) {
        let eye = Quat::from_rotation_y(turn) * Vec3::from(eye);
        prop_assume!(eye.length() > 0.5 && (eye.x.abs() > 1e-3 || eye.z.abs() > 1e-3));
        let look = LookAt { eye, target: Vec3::ZERO, up: Vec3::Y, fovy: Angle::degrees(60.0), near: 0.05, far: 40.0 };
        let cam = Camera::perspective(&look, w as f32 / h as f32).unwrap();
        let soup = Soup::from_triangles(tris.clone());
        let mut fb = Framebuffer::new(w, h).unwrap();
        let c = warnock::render_with(&soup, &cam, &mut fb, &Options { backface_culling: cull }).unwrap();
        // A quadtree whose leaves are at least single pixels has fewer than two windows a pixel.
        prop_assert!(c.get("windows").unwrap() < 2 * (w * h) as u64 + 1, "{c:?}");
        prop_assert!(fb.ids.iter().all(|&i| i as usize <= tris.len()));
        prop_assert!(fb.depth.iter().all(|d| (0.0..=1.0).contains(d)));
        // Still the z-buffer's IDs, pixel for pixel.
        if !tris.is_empty() {
            let mut z = Framebuffer::new(w, h).unwrap();
            let opts = RenderOptions { backface_culling: cull, ..RenderOptions::ids_only() };
            render_scene(&soup_scene(&tris), &cam, &mut z, &opts).unwrap();
            prop_assert_eq!(&z.ids, &fb.ids);
        }
    }
}

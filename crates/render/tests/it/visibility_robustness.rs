//! The lab's object-order methods on hostile soups: random triangles on a coarse grid (so
//! repeated vertices, collinear corners, coplanar and coincident triangles are common),
//! points, needles, stacks of coplanar copies, from perspective and parallel cameras. Every
//! method must end, within a time bound, in `Ok` with IDs of the soup or background, or in
//! one of the errors that name a limit; never a panic.

use std::sync::mpsc;
use std::time::Duration;

use glam::Vec3;
use proptest::prelude::*;
use sightline_render::visibility::{bsp, painter, BspMode, Soup};
use sightline_render::{Error, Framebuffer};
use sightline_scene::{Angle, Camera, LookAt, Projection, View};

const W: u32 = 48;
const H: u32 = 40;

/// A grid point: coordinates in steps of 0.5 in [−1.5, 1.5].
fn grid_point() -> impl Strategy<Value = Vec3> {
    (-3i8..=3, -3i8..=3, -3i8..=3).prop_map(|(x, y, z)| Vec3::new(x as f32, y as f32, z as f32) * 0.5)
}

fn triangle() -> impl Strategy<Value = [Vec3; 3]> {
    prop_oneof![
        4 => [grid_point(), grid_point(), grid_point()],
        // In the plane z = 0, like every other of its kind: coplanar overlaps.
        2 => [grid_point(), grid_point(), grid_point()].prop_map(|t| t.map(|p| Vec3::new(p.x, p.y, 0.0))),
        // A point.
        1 => grid_point().prop_map(|p| [p; 3]),
        // Collinear corners.
        1 => (grid_point(), grid_point()).prop_map(|(p, d)| [p, p + d, p + d * 2.0]),
        // Two corners repeated.
        1 => (grid_point(), grid_point()).prop_map(|(p, q)| [p, q, q]),
    ]
}

/// A soup, with some triangles repeated exactly (coincident copies, in both windings).
fn soup() -> impl Strategy<Value = Vec<[Vec3; 3]>> {
    (proptest::collection::vec(triangle(), 0..10), proptest::collection::vec(any::<u8>(), 0..4)).prop_map(
        |(mut tris, copies)| {
            for c in copies {
                if !tris.is_empty() {
                    let t = tris[c as usize % tris.len()];
                    tris.push(if c % 2 == 0 { t } else { [t[0], t[2], t[1]] });
                }
            }
            tris
        },
    )
}

fn camera(eye: Vec3, ortho: bool) -> Camera {
    let eye = if eye.length() < 0.1 { Vec3::new(0.0, 0.0, 5.0) } else { eye };
    if ortho {
        let view = View::look_at(eye, Vec3::ZERO, Vec3::Y)
            .unwrap_or_else(|_| View::look_at(eye, Vec3::ZERO, Vec3::X).unwrap());
        Camera::new(view, Projection::orthographic(-2.0, 2.0, -1.7, 1.7, 0.1, 20.0).unwrap()).unwrap()
    } else {
        let up = if eye.cross(Vec3::Y).length() < 1e-3 { Vec3::X } else { Vec3::Y };
        let look = LookAt { eye, target: Vec3::ZERO, up, fovy: Angle::degrees(60.0), near: 0.1, far: 20.0 };
        Camera::perspective(&look, W as f32 / H as f32).unwrap()
    }
}

/// Every method on `tris`; panics (failing the case) on a wrong outcome.
fn run_all(tris: Vec<[Vec3; 3]>, cam: Camera) {
    let soup = Soup::from_triangles(tris);
    let n = soup.len() as u32;
    let mut fb = Framebuffer::new(W, H).unwrap();
    let check =
        |what: &str, r: sightline_render::Result<sightline_render::visibility::Counters>, fb: &Framebuffer| match r {
            Ok(_) => {
                assert!(fb.ids.iter().all(|&i| i <= n), "{what}: an ID outside the soup");
                assert!(fb.depth.iter().all(|d| (0.0..=1.0).contains(d)), "{what}: depth outside [0, 1]");
            }
            Err(Error::LimitExceeded { .. } | Error::TooLarge { .. }) => {}
            Err(e) => panic!("{what}: unexpected error {e}"),
        };
    let r = painter::render(&soup, &cam, &mut fb);
    check("painter", r, &fb);
    let r = painter::render_centroid_sort(&soup, &cam, &mut fb);
    check("centroid sort", r, &fb);
    for mode in [BspMode::BackToFront, BspMode::FrontToBack] {
        let r = bsp::render(&soup, &cam, &mut fb, mode);
        check("bsp", r, &fb);
    }
}

/// Runs `f` on another thread and fails if it has not finished within a generous bound
/// (a hang fails the test instead of stalling the run).
fn within_time(f: impl FnOnce() + Send + 'static) {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        f();
        let _ = tx.send(());
    });
    match rx.recv_timeout(Duration::from_secs(30)) {
        Ok(()) => {}
        Err(mpsc::RecvTimeoutError::Disconnected) => panic!("a method panicked (see above)"),
        Err(mpsc::RecvTimeoutError::Timeout) => panic!("a method did not finish within 30 s"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn hostile_soups_end_in_ok_or_a_named_limit(
        tris in soup(),
        eye in (-6.0f32..6.0, -6.0f32..6.0, -6.0f32..6.0),
        ortho in any::<bool>(),
    ) {
        let cam = camera(Vec3::new(eye.0, eye.1, eye.2), ortho);
        within_time(move || run_all(tris, cam));
    }
}

/// A stack of coincident copies and a fan of triangles sharing one edge, from three sides:
/// ties everywhere, still drawn.
#[test]
fn coincident_stacks_and_fans_are_drawn() {
    let t = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
    let mut tris = vec![t; 12];
    for k in 0..12 {
        let a = k as f32 * 0.5;
        tris.push([Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, a.cos(), a.sin())]);
    }
    for eye in [Vec3::new(0.2, 0.3, 5.0), Vec3::new(3.0, 1.0, 2.0), Vec3::new(0.1, 4.0, 2.0)] {
        let soup = Soup::from_triangles(tris.clone());
        let cam = camera(eye, false);
        let mut fb = Framebuffer::new(W, H).unwrap();
        painter::render(&soup, &cam, &mut fb).unwrap();
        assert!(fb.ids.iter().any(|&i| i != 0));
        bsp::render(&soup, &cam, &mut fb, BspMode::BackToFront).unwrap();
        assert!(fb.ids.iter().any(|&i| i != 0));
    }
}

//! Hidden-line wireframe: edges are depth-tested against the filled frame, so an edge behind
//! a front-facing quad disappears where the quad covers it and shows where it does not,
//! while the quad's own edges (and the shared diagonal) are drawn.

use glam::Vec3;
use sightline_render::{render_scene, Framebuffer, RenderOptions, Wireframe};
use sightline_scene::{Angle, Camera, LookAt, Mesh};

use crate::support::one_node_scene;

const WIRE: [u8; 4] = [255, 0, 255, 255];
const N: u32 = 128;

/// A quad at z = 0 facing the camera, and behind it (z = −1) a wide triangle whose bottom
/// edge runs along y = −0.2, across the quad and out past both its sides.
fn scene() -> (sightline_scene::Scene, Camera) {
    let p = vec![
        Vec3::new(-0.5, -0.5, 0.0),
        Vec3::new(0.5, -0.5, 0.0),
        Vec3::new(0.5, 0.5, 0.0),
        Vec3::new(-0.5, 0.5, 0.0),
        Vec3::new(-1.8, -0.2, -1.0),
        Vec3::new(1.8, -0.2, -1.0),
        Vec3::new(0.0, 1.2, -1.0),
    ];
    let mesh = Mesh::new("m", p, None, None, vec![0, 1, 2, 0, 2, 3, 4, 5, 6]).unwrap();
    let look = LookAt {
        eye: Vec3::new(0.0, 0.0, 4.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fovy: Angle::degrees(40.0),
        near: 0.5,
        far: 20.0,
    };
    (one_node_scene("m", mesh), Camera::perspective(&look, 1.0).unwrap())
}

/// Wire pixels in row band `rows` and column band `cols`.
fn wire_in(fb: &Framebuffer, rows: std::ops::Range<u32>, cols: std::ops::Range<u32>) -> usize {
    rows.flat_map(|y| cols.clone().map(move |x| (x, y))).filter(|&(x, y)| fb.color[fb.index(x, y)] == WIRE).count()
}

#[test]
fn hidden_edges_disappear_and_visible_ones_stay() {
    let (s, cam) = scene();
    let draw = |mode| {
        let mut fb = Framebuffer::new(N, N).unwrap();
        let o = RenderOptions { wireframe: mode, wire_color: WIRE, ..Default::default() };
        render_scene(&s, &cam, &mut fb, &o).unwrap();
        fb
    };
    let (hidden, overlay) = (draw(Wireframe::HiddenLine), draw(Wireframe::Overlay));
    // Where the back triangle's bottom edge projects: y = −0.2 at distance 5.
    let f = 1.0 / (20f32.to_radians().tan());
    let row = ((1.0 - f * -0.2 / 5.0) * 0.5 * N as f32) as u32;
    let quad_px = |x: f32| ((f * x / 4.0 + 1.0) * 0.5 * N as f32) as u32;
    let (q0, q1) = (quad_px(-0.5), quad_px(0.5));
    let band = row - 1..row + 2;
    // Inside the quad's columns, away from its side edges and from its diagonal (which
    // crosses these rows where x = y on the quad: y = −0.2 · 4/5), the back edge is hidden...
    let diagonal = quad_px(-0.16);
    let inside = q0 + 3..diagonal - 2;
    assert!(inside.len() >= 8);
    assert!(wire_in(&overlay, band.clone(), inside.clone()) >= (inside.len() - 2), "overlay draws it");
    assert_eq!(wire_in(&hidden, band.clone(), inside.clone()), 0, "hidden-line mode hides it");
    let inside = diagonal + 3..q1 - 3;
    assert_eq!(wire_in(&hidden, band.clone(), inside), 0, "hidden-line mode hides it");
    // ...and shown outside them, where nothing covers it.
    let outside = 2..q0 - 2;
    assert!(wire_in(&hidden, band.clone(), outside.clone()) >= outside.len() - 1, "visible part drawn");
    // The quad's own edges (top and bottom rows, sides, diagonal) are all drawn.
    let quad_rows = |y: f32| ((1.0 - f * y / 4.0) * 0.5 * N as f32) as u32;
    let (top, bottom) = (quad_rows(0.5), quad_rows(-0.5));
    assert!(wire_in(&hidden, top - 1..top + 1, q0 + 1..q1 - 1) >= (q1 - q0 - 3) as usize);
    assert!(wire_in(&hidden, bottom - 1..bottom + 1, q0 + 1..q1 - 1) >= (q1 - q0 - 3) as usize);
    assert!(wire_in(&hidden, top + 2..bottom - 2, q0 - 1..q0 + 2) >= (bottom - top - 5) as usize);
    let all = |fb: &Framebuffer| fb.color.iter().filter(|&&c| c == WIRE).count();
    // The diagonal plus the quad outline stay, the hidden run goes: fewer pixels than overlay.
    assert!(all(&hidden) + (q1 - q0 - 8) as usize <= all(&overlay), "{} vs {}", all(&hidden), all(&overlay));
    // Filled planes are the same in both modes: only line pixels differ.
    assert_eq!(hidden.ids, overlay.ids);
}

/// A grazing surface (a floor seen at a low angle) keeps its edges: the slope-scaled
/// tolerance covers the depth change across half a pixel.
#[test]
fn edges_of_grazing_surfaces_stay_visible() {
    let p = vec![
        Vec3::new(-2.0, 0.0, -8.0),
        Vec3::new(2.0, 0.0, -8.0),
        Vec3::new(2.0, 0.0, 2.0),
        Vec3::new(-2.0, 0.0, 2.0),
    ];
    let s = one_node_scene("floor", Mesh::new("floor", p, None, None, vec![0, 2, 1, 0, 3, 2]).unwrap());
    let look = LookAt {
        eye: Vec3::new(0.3, 0.4, 3.0),
        target: Vec3::new(0.0, 0.0, -3.0),
        up: Vec3::Y,
        fovy: Angle::degrees(60.0),
        near: 0.1,
        far: 30.0,
    };
    let cam = Camera::perspective(&look, 1.0).unwrap();
    let count = |mode| {
        let mut fb = Framebuffer::new(N, N).unwrap();
        let o = RenderOptions { wireframe: mode, wire_color: WIRE, ..Default::default() };
        render_scene(&s, &cam, &mut fb, &o).unwrap();
        assert!(fb.ids.iter().filter(|&&i| i != 0).count() > 500);
        fb.color.iter().filter(|&&c| c == WIRE).count()
    };
    let (hidden, overlay) = (count(Wireframe::HiddenLine), count(Wireframe::Overlay));
    assert!(overlay > 60, "{overlay}");
    assert_eq!(hidden, overlay, "no edge of a lone floor is hidden");
}

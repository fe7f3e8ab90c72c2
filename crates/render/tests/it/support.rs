//! Fixtures shared by the modules of this test binary: scene builders, pixel-center NDC,
//! frame comparison.

use glam::Vec2;
use sightline_render::Framebuffer;
use sightline_scene::builders::{city, City, CityParams};
use sightline_scene::{Mesh, NodeDesc, Scene};

/// The 30,000-triangle city.
pub fn small_city() -> City {
    city(&CityParams::for_triangles(30_000)).unwrap()
}

/// A scene of one node `name` drawing `mesh`, transforms propagated.
pub fn one_node_scene(name: &str, mesh: Mesh) -> Scene {
    let mut s = Scene::new();
    let m = s.add_mesh(mesh);
    s.add_node(None, NodeDesc::new(name).mesh(m)).unwrap();
    s.update_transforms();
    s
}

/// NDC of the center of pixel (x, y) of a w × h image, row 0 at the top.
pub fn pixel_ndc(x: u32, y: u32, w: u32, h: u32) -> Vec2 {
    Vec2::new(2.0 * (x as f32 + 0.5) / w as f32 - 1.0, 1.0 - 2.0 * (y as f32 + 0.5) / h as f32)
}

/// Asserts that two frames hold the same IDs, colors and depths, depths compared bit for bit.
pub fn assert_bit_identical(a: &Framebuffer, b: &Framebuffer, what: &str) {
    assert_eq!(a.ids, b.ids, "{what}: IDs differ");
    assert_eq!(a.color, b.color, "{what}: colors differ");
    let bits = |f: &Framebuffer| f.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(a), bits(b), "{what}: depths differ");
}

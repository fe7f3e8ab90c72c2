//! Determinism: the same color, depth and ID buffers bit for bit with 1 and 2 threads.

use sightline_render::{draw_all, Antialias, Framebuffer, RenderOptions, Renderer, ShadingMode};
use sightline_scene::builders::{city, CityParams};

use crate::support::assert_bit_identical;

fn render_with(threads: usize, opts: &RenderOptions, street: bool) -> Framebuffer {
    let c = city(&CityParams::for_triangles(40_000)).unwrap();
    let instances = c.scene.instances();
    let items = draw_all(&instances);
    let key = if street { c.layout.street_path(10, 11)[3] } else { c.layout.aerial_path(10)[3] };
    let cam = key.camera(16.0 / 9.0).unwrap();
    let mut fb = Framebuffer::new(320, 180).unwrap();
    fb.count_depth_tests(true);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| Renderer::new().render(&c.scene, &instances, &items, &cam, &mut fb, opts).unwrap());
    fb
}

#[test]
fn one_and_two_threads_give_identical_buffers() {
    let gouraud = {
        let mut o = RenderOptions { backface_culling: false, ..RenderOptions::default() };
        o.shading.mode = ShadingMode::Gouraud;
        o
    };
    let ssaa = RenderOptions { antialias: Antialias::Ssaa2x2, ..RenderOptions::default() };
    for (opts, street) in [(RenderOptions::default(), true), (gouraud, false), (ssaa, true)] {
        let a = render_with(1, &opts, street);
        let b = render_with(2, &opts, street);
        assert!(a.ids.iter().any(|&i| i != 0));
        assert_bit_identical(&a, &b, "1 and 2 threads");
        assert_eq!(a.depth_tests, b.depth_tests);
    }
}

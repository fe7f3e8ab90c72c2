//! Masked and blended materials: the mask test, the A-buffer against compositing worked out
//! by hand, depth peeling against the A-buffer, and opaque frames left as they were.

use std::sync::Arc;

use glam::{Affine3A, Quat, Vec2, Vec3};
use sightline_render::texture::Filter;
use sightline_render::{
    draw_all, render_abuffer, render_depth_peeling, scene_has_transparency, Antialias, DepthFormat, Error, Framebuffer,
    RenderOptions, Renderer, ShadeOptions, Transparency,
};
use sightline_scene::rng::Rng;
use sightline_scene::{
    AlphaMode, Angle, Camera, LookAt, Material, Mesh, NodeDesc, Projection, Scene, Texture, Transform, View,
};

use crate::support::{assert_bit_identical, small_city};

const SIZE: u32 = 64;
const WHITE: [f32; 3] = [1.0, 1.0, 1.0];

/// The quad `[x0, x1] × [y0, y1]` at height `z`, facing +z, UVs (0, 0) at its top left.
fn quad(name: &str, [x0, y0, x1, y1]: [f32; 4], z: f32) -> Mesh {
    let p = vec![Vec3::new(x0, y0, z), Vec3::new(x1, y0, z), Vec3::new(x1, y1, z), Vec3::new(x0, y1, z)];
    let uv = vec![Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.0)];
    Mesh::new(name, p, Some(vec![Vec3::Z; 4]), Some(uv), vec![0, 1, 2, 0, 2, 3]).unwrap()
}

/// Adds a node drawing `mesh` with `material`; returns the ID of its first triangle.
fn add(s: &mut Scene, mesh: Mesh, material: Material) -> u32 {
    let first = s.stats().triangles as u32 + 1;
    let (m, mat) = (s.add_mesh(mesh), s.add_material(material));
    s.add_node(None, NodeDesc::new("n").mesh(m).material(mat)).unwrap();
    s.update_transforms();
    first
}

fn blended(rgb: [f32; 3], alpha: f32) -> Material {
    Material::translucent("glass", rgb, alpha)
}

/// Looking down −z at the square [−2, 2]² (orthographic): pixel (i, j) of the 64 × 64 frame
/// sees world (−2 + (i + ½)/16, 2 − (j + ½)/16).
fn top_camera() -> Camera {
    let view = View::look_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y).unwrap();
    Camera::new(view, Projection::orthographic(-2.0, 2.0, -2.0, 2.0, 0.1, 100.0).unwrap()).unwrap()
}

/// Unlit (color = base color), on black.
fn unlit() -> RenderOptions {
    RenderOptions { shading: ShadeOptions::unlit(), background: [0, 0, 0, 255], ..RenderOptions::default() }
}

/// The pixel seeing world point (x, y) in the [`top_camera`] frame.
fn at(x: f32, y: f32) -> usize {
    let i = ((x + 2.0) * 16.0) as usize;
    let j = ((2.0 - y) * 16.0) as usize;
    j * SIZE as usize + i
}

fn frame() -> Framebuffer {
    Framebuffer::new(SIZE, SIZE).unwrap()
}

/// RGBA8 of linear [0, 1] RGB worked out in f64, alpha 1.
fn rgb8(c: [f64; 3]) -> [u8; 4] {
    let q = |v: f64| (v * 255.0 + 0.5) as u8;
    [q(c[0]), q(c[1]), q(c[2]), 255]
}

/// `src` (alpha `a`) over `dst`, in f64.
fn over(src: [f64; 3], a: f64, dst: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|k| a * src[k] + (1.0 - a) * dst[k])
}

#[test]
fn mask_discards_fragments_below_the_cutoff() {
    let mut s = Scene::new();
    let wall = add(&mut s, quad("wall", [-2.0, -2.0, 2.0, 2.0], -1.0), Material::color("wall", WHITE));
    // Left texel opaque, right texel transparent; nearest filtering splits the quad in two.
    let tex = Texture::new(2, 1, vec![255, 0, 0, 255, 255, 0, 0, 0]).unwrap();
    let cutout = Material { base_color_texture: Some(Arc::new(tex)), ..Material::color("cutout", WHITE) }
        .with_alpha_mode(AlphaMode::mask());
    let cut = add(&mut s, quad("cutout", [-1.5, 0.5, 1.5, 1.5], 0.0), cutout);
    // Factor alpha 0.4: below the default cutoff, above 0.3; a NaN cutoff keeps nothing.
    let faint = |cutoff: f32| {
        Material { base_color: [0.0, 1.0, 0.0, 0.4], ..Material::default() }.with_alpha_mode(AlphaMode::Mask { cutoff })
    };
    let low = add(&mut s, quad("low", [-1.5, -0.5, -0.5, 0.0], 0.0), faint(0.5));
    let high = add(&mut s, quad("high", [0.5, -0.5, 1.5, 0.0], 0.0), faint(0.3));
    let nan = add(&mut s, quad("nan", [-1.5, -1.5, 1.5, -1.0], 0.0), faint(f32::NAN));

    let mut opts = unlit();
    opts.shading.filter = Filter::Nearest;
    let mut fb = frame();
    let st = render_abuffer(&s, &top_camera(), &mut fb, &opts).unwrap();
    let mut walls_only = frame();
    let mut bare = Scene::new();
    add(&mut bare, quad("wall", [-2.0, -2.0, 2.0, 2.0], -1.0), Material::color("wall", WHITE));
    render_abuffer(&bare, &top_camera(), &mut walls_only, &opts).unwrap();

    let kept = |p: usize, id: u32| {
        assert!(fb.ids[p] == id || fb.ids[p] == id + 1, "pixel {p}: id {} not of quad {id}", fb.ids[p]);
        assert!(fb.depth[p] < walls_only.depth[p]);
    };
    let hole = |p: usize, what: &str| {
        assert!(fb.ids[p] == wall || fb.ids[p] == wall + 1, "{what}: the wall shows through");
        assert_eq!(fb.depth[p].to_bits(), walls_only.depth[p].to_bits(), "{what}: no depth written");
        assert_eq!(fb.color[p], [255, 255, 255, 255], "{what}");
    };
    kept(at(-1.0, 1.0), cut);
    assert_eq!(fb.color[at(-1.0, 1.0)], [255, 0, 0, 255], "kept and drawn opaque");
    hole(at(1.0, 1.0), "transparent texel");
    hole(at(-1.0, -0.25), "alpha 0.4 < cutoff 0.5");
    kept(at(1.0, -0.25), high);
    assert_eq!(fb.color[at(1.0, -0.25)], [0, 255, 0, 255], "alpha 0.4 ≥ 0.3: opaque green");
    hole(at(0.0, -1.25), "NaN cutoff");
    assert!(fb.ids.iter().all(|&i| i != low && i != low + 1 && i != nan && i != nan + 1));
    let t = st;
    assert_eq!(t.masked_triangles, 8);
    // Each quad's fragments all pass the depth test: kept + discarded = covered.
    let area = |w: f32, h: f32| (w * 16.0 * h * 16.0) as u64;
    let covered = area(3.0, 1.0) + 2 * area(1.0, 0.5) + area(3.0, 0.5);
    assert_eq!(t.masked_fragments_kept + t.masked_fragments_discarded, covered);
    assert_eq!(t.masked_fragments_kept, area(1.5, 1.0) + area(1.0, 0.5));
    // Ignoring alpha modes draws every quad whole.
    let mut ignore = frame();
    Renderer::new()
        .render(
            &s,
            &s.instances(),
            &draw_all(&s.instances()),
            &top_camera(),
            &mut ignore,
            &RenderOptions { transparency: Transparency::Ignore, ..opts },
        )
        .unwrap();
    assert!(ignore.ids[at(1.0, 1.0)] >= cut && ignore.ids[at(0.0, -1.25)] >= nan);
}

/// Three overlapping blended quads (blue nearest but first in ID order), a textured one whose
/// alpha is the texture's, and one hidden behind the wall.
fn glass_scene() -> (Scene, [u32; 5]) {
    let mut s = Scene::new();
    let wall = add(&mut s, quad("wall", [-2.0, -2.0, 2.0, 2.0], -1.0), Material::color("wall", WHITE));
    let blue = add(&mut s, quad("blue", [-0.5, -1.5, 1.5, 0.5], 1.0), blended([0.0, 0.0, 1.0], 0.2));
    let red = add(&mut s, quad("red", [-1.5, -0.5, 0.5, 1.5], 0.0), blended([1.0, 0.0, 0.0], 0.6));
    add(&mut s, quad("green", [-1.0, -1.0, 1.0, 1.0], 0.5), blended([0.0, 1.0, 0.0], 0.4));
    let tex = Texture::new(1, 1, vec![255, 255, 255, 102]).unwrap();
    let textured = Material { base_color_texture: Some(Arc::new(tex)), ..blended([0.0, 0.0, 1.0], 1.0) };
    let tq = add(&mut s, quad("textured", [1.0, 1.0, 1.8, 1.8], 0.2), textured);
    add(&mut s, quad("hidden", [-1.8, -1.8, -1.2, -1.2], -1.5), blended([1.0, 0.0, 1.0], 0.5));
    (s, [wall, blue, red, tq, 0])
}

#[test]
fn abuffer_equals_compositing_by_hand() {
    let (s, [wall, blue, red, tq, _]) = glass_scene();
    assert!(scene_has_transparency(&s));
    let mut fb = frame();
    let st = render_abuffer(&s, &top_camera(), &mut fb, &unlit()).unwrap();
    let (r, g, b, w) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0; 3]);
    // Back to front: red (z 0), green (z 0.5), blue (z 1), over the white wall.
    let three = over(b, 0.2, over(g, 0.4, over(r, 0.6, w)));
    assert_eq!(fb.color[at(0.0, 0.0)], rgb8(three));
    assert_eq!(rgb8(three), [122, 131, 100, 255]);
    assert_eq!(fb.color[at(-0.8, 0.8)], rgb8(over(g, 0.4, over(r, 0.6, w))));
    assert_eq!(fb.color[at(1.2, -1.2)], rgb8(over(b, 0.2, w)));
    // Texture alpha 102/255 = 0.4 times factor alpha 1.
    assert_eq!(fb.color[at(1.4, 1.4)], rgb8(over(b, 0.4, w)));
    // Behind the opaque wall: nothing.
    assert_eq!(fb.color[at(-1.5, -1.5)], [255, 255, 255, 255]);
    assert!(fb.ids[at(-1.5, -1.5)] >= wall && fb.ids[at(-1.5, -1.5)] <= wall + 1);
    // IDs and depth: the nearest surface, blended or not.
    assert!(fb.ids[at(0.0, 0.0)] >= blue && fb.ids[at(0.0, 0.0)] <= blue + 1);
    assert!(fb.ids[at(-0.8, 0.8)] == red + 2 || fb.ids[at(-0.8, 0.8)] == red + 3, "green is nearest there");
    assert!(fb.ids[at(1.4, 1.4)] >= tq);
    assert!(fb.depth[at(0.0, 0.0)] < fb.depth[at(-0.8, 0.8)]);
    // Counters: three quads of 32 × 32 pixels and 13 × 13 textured ones in front; three deep.
    assert_eq!(st.blended_triangles, 10);
    assert_eq!(st.fragments, 3 * 1024 + 169);
    assert_eq!((st.max_fragments_per_pixel, st.layers), (3, 3));
    assert!(st.pixels > 1024 && st.pixels < st.fragments);
    assert!((st.mean_fragments_per_pixel - st.fragments as f64 / st.pixels as f64).abs() < 1e-12);
    // The hidden quad is drawn (and rejected) too.
    assert!(st.fragments_drawn > st.fragments);
    // Supersampled, the same inside the quads (the samples of a pixel agree there).
    let mut ss = frame();
    let opts = RenderOptions { antialias: Antialias::Ssaa2x2, ..unlit() };
    let st2 = render_abuffer(&s, &top_camera(), &mut ss, &opts).unwrap();
    assert_eq!(st2.fragments, 3 * 4096 + 26 * 26, "samples, 128 × 128 of them");
    for p in [at(0.0, 0.0), at(-0.8, 0.8), at(1.2, -1.2), at(1.4, 1.4)] {
        assert_eq!(ss.color[p], fb.color[p], "pixel {p}");
    }
}

#[test]
fn coplanar_blended_layers_are_neither_lost_nor_doubled() {
    let mut s = Scene::new();
    add(&mut s, quad("wall", [-2.0, -2.0, 2.0, 2.0], -1.0), Material::color("wall", WHITE));
    let first = add(&mut s, quad("red", [-1.0, -1.0, 1.0, 1.0], 0.0), blended([1.0, 0.0, 0.0], 0.6));
    add(&mut s, quad("green", [-1.0, -1.0, 1.0, 1.0], 0.0), blended([0.0, 1.0, 0.0], 0.4));
    // Equal depths: the smaller ID (red) is in front, as in the z-buffer.
    let want = rgb8(over([1.0, 0.0, 0.0], 0.6, over([0.0, 1.0, 0.0], 0.4, [1.0; 3])));
    let mut a = frame();
    render_abuffer(&s, &top_camera(), &mut a, &unlit()).unwrap();
    assert_eq!(a.color[at(0.0, 0.0)], want);
    assert!(a.ids[at(0.0, 0.0)] == first || a.ids[at(0.0, 0.0)] == first + 1);
    for layers in [2, 3, 10] {
        let mut p = frame();
        let st = render_depth_peeling(&s, &top_camera(), &mut p, layers, &unlit()).unwrap();
        assert_eq!((st.layers, st.pixels_missing_layers), (2, 0));
        assert_eq!(p.color[at(0.0, 0.0)], want, "{layers} layers");
        assert_eq!(p.ids, a.ids);
    }
    let mut one = frame();
    let st = render_depth_peeling(&s, &top_camera(), &mut one, 1, &unlit()).unwrap();
    assert_eq!(one.color[at(0.0, 0.0)], rgb8(over([1.0, 0.0, 0.0], 0.6, [1.0; 3])), "only the front layer");
    assert_eq!((st.layers, st.pixels_missing_layers), (1, 1024));
}

/// Pixels whose color differs from `b`'s by more than `tol` in some channel.
fn differing(a: &Framebuffer, b: &Framebuffer, tol: u8) -> usize {
    a.color.iter().zip(&b.color).filter(|(x, y)| (0..4).any(|k| x[k].abs_diff(y[k]) > tol)).count()
}

/// Depth peeling with 1, 2, … layers against the A-buffer: equal (colors within 1/255, same
/// IDs and depths) from the deepest list on, and ever closer before.
fn peeling_converges(s: &Scene, camera: &Camera, opts: &RenderOptions, what: &str) {
    let (w, h) = (96, 72);
    let mut a = Framebuffer::new(w, h).unwrap();
    let ref_st = render_abuffer(s, camera, &mut a, opts).unwrap();
    let deepest = ref_st.max_fragments_per_pixel;
    assert!(deepest >= 3, "{what}: a scene three layers deep at least, got {deepest}");
    let mut last = usize::MAX;
    for layers in [1, 2, deepest - 1, deepest, deepest + 5] {
        let mut p = Framebuffer::new(w, h).unwrap();
        let st = render_depth_peeling(s, camera, &mut p, layers, opts).unwrap();
        let diff = differing(&p, &a, 1);
        assert_eq!(st.fragments, ref_st.fragments, "{what}");
        assert_eq!(st.max_fragments_per_pixel, deepest, "{what}");
        assert_eq!(p.ids, a.ids, "{what}, {layers} layers: the nearest surfaces");
        if layers >= deepest {
            assert_eq!(diff, 0, "{what}, {layers} layers: equal to the A-buffer");
            assert_eq!((st.layers, st.pixels_missing_layers), (deepest, 0), "{what}");
            let bits = |f: &Framebuffer| f.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&p), bits(&a), "{what}");
        } else {
            assert!(st.pixels_missing_layers > 0, "{what}, {layers} layers: some pixels lack layers");
            // (A layer behind many others may add less than 1/255: only few layers must show.)
            assert!(layers > 2 || diff > 0, "{what}, {layers} layers: must degrade");
            assert!(diff <= st.pixels_missing_layers as usize, "{what}: only pixels missing layers differ");
            assert!(diff <= last, "{what}: more layers, fewer wrong pixels ({diff} after {last})");
            assert_eq!(st.layers, layers, "{what}");
        }
        last = diff;
    }
}

#[test]
fn depth_peeling_converges_to_the_abuffer_on_the_glass_scene() {
    let (s, _) = glass_scene();
    let cam =
        Camera::perspective(&LookAt { eye: Vec3::new(1.0, -2.0, 6.0), far: 50.0, ..LookAt::default() }, 4.0 / 3.0);
    peeling_converges(&s, &cam.unwrap(), &RenderOptions::default(), "glass scene");
}

#[test]
fn depth_peeling_converges_to_the_abuffer_on_the_asset() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/transparent.gltf");
    let s = sightline_scene::load(path).unwrap();
    assert!(scene_has_transparency(&s));
    let look = LookAt { eye: Vec3::new(4.86, 6.32, 0.64), fovy: Angle::degrees(45.0), far: 100.0, ..LookAt::default() };
    peeling_converges(&s, &Camera::perspective(&look, 4.0 / 3.0).unwrap(), &RenderOptions::default(), "asset");
}

/// Random tilted quads crossing each other (interpenetrating, coplanar pairs included),
/// blended, masked and opaque, both faces drawn.
fn soup(seed: u64) -> Scene {
    let mut rng = Rng::new(seed);
    let mut s = Scene::new();
    let tex =
        Arc::new(Texture::new(2, 2, vec![255, 255, 255, 255, 9, 9, 9, 0, 90, 90, 90, 120, 200, 9, 9, 60]).unwrap());
    for k in 0..40 {
        let (col, alpha, twin) = (rgb(&mut rng), rng.range(0.1, 0.9), rgb(&mut rng));
        let material = match k % 5 {
            0 => Material::color("opaque", col),
            1 => Material { base_color_texture: Some(tex.clone()), ..Material::color("mask", col) }
                .with_alpha_mode(AlphaMode::Mask { cutoff: 0.4 }),
            2 => Material { base_color_texture: Some(tex.clone()), ..blended(col, 1.0) },
            _ => blended(col, alpha),
        };
        let mesh = s.add_mesh(quad("q", [-0.6, -0.6, 0.6, 0.6], 0.0));
        let mat = s.add_material(material);
        // Every fourth quad repeats the last placement: coplanar pairs.
        let q = Quat::from_euler(glam::EulerRot::XYZ, rng.range(-1.2, 1.2), rng.range(-1.2, 1.2), rng.range(-3.0, 3.0));
        let t = Vec3::new(rng.range(-1.2, 1.2), rng.range(-1.2, 1.2), rng.range(-1.0, 1.0));
        let place = Transform::from_affine(&Affine3A::from_rotation_translation(q, t));
        s.add_node(None, NodeDesc::new("q").mesh(mesh).material(mat).transform(place)).unwrap();
        if k % 4 == 3 {
            let m2 = s.add_material(blended(twin, 0.5));
            s.add_node(None, NodeDesc::new("twin").mesh(mesh).material(m2).transform(place)).unwrap();
        }
    }
    s.update_transforms();
    s
}

fn rgb(rng: &mut Rng) -> [f32; 3] {
    [rng.range(0.1, 1.0), rng.range(0.1, 1.0), rng.range(0.1, 1.0)]
}

#[test]
fn depth_peeling_converges_to_the_abuffer_on_random_soups() {
    for seed in 1..4 {
        let s = soup(seed);
        let look = LookAt { eye: Vec3::new(0.5, 0.3, 5.0), far: 20.0, ..LookAt::default() };
        let cam = Camera::perspective(&look, 4.0 / 3.0).unwrap();
        for fmt in [DepthFormat::F32, DepthFormat::Unorm16] {
            let opts = RenderOptions { backface_culling: false, depth_format: fmt, ..RenderOptions::default() };
            peeling_converges(&s, &cam, &opts, &format!("soup {seed}, {fmt:?}"));
        }
    }
}

#[test]
fn opaque_frames_are_unchanged_by_the_transparency_paths() {
    let city = small_city();
    let cam = city.layout.street_path(10, 11)[2].camera(4.0 / 3.0).unwrap();
    let mut scene = city.scene;
    let opts = RenderOptions::default();
    let draw = |s: &Scene, how: Transparency| {
        let mut fb = Framebuffer::new(160, 120).unwrap();
        let inst = s.instances();
        let o = RenderOptions { transparency: how, ..opts };
        Renderer::new().render(s, &inst, &draw_all(&inst), &cam, &mut fb, &o).unwrap();
        fb
    };
    let plain = draw(&scene, Transparency::Ignore);
    assert!(!scene_has_transparency(&scene));
    for how in [Transparency::ABuffer, Transparency::DepthPeeling { layers: 2 }] {
        assert_bit_identical(&draw(&scene, how), &plain, &format!("opaque city, {how:?}"));
    }
    // A blended quad under the ground and a masked one of alpha 0 in front of the camera (IDs
    // after the city's) send the frame down the transparency paths: the opaque part is drawn
    // as before, bit for bit.
    let eye = cam.view.eye;
    let under = scene.add_mesh(quad("under", [-20.0, -20.0, 20.0, 20.0], 0.0));
    let m = scene.add_material(blended([1.0, 0.0, 0.0], 0.5));
    let down = Transform::from_affine(&Affine3A::from_rotation_translation(
        Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2),
        Vec3::new(eye.x, -5.0, eye.z),
    ));
    scene.add_node(None, NodeDesc::new("under").mesh(under).material(m).transform(down)).unwrap();
    let clear = Material { base_color: [1.0, 1.0, 1.0, 0.0], ..Material::default() }.with_alpha_mode(AlphaMode::mask());
    let veil = scene.add_mesh(quad("veil", [-1e3, -1e3, 1e3, 1e3], 0.0));
    let m = scene.add_material(clear);
    let look = city_look_transform(&cam);
    scene.add_node(None, NodeDesc::new("veil").mesh(veil).material(m).transform(look)).unwrap();
    scene.update_transforms();
    assert!(scene_has_transparency(&scene));
    for how in [Transparency::ABuffer, Transparency::DepthPeeling { layers: 3 }] {
        assert_bit_identical(&draw(&scene, how), &plain, &format!("city with hidden glass, {how:?}"));
    }
}

/// A transform putting a +z-facing quad across the view, one unit in front of the eye.
fn city_look_transform(cam: &Camera) -> Transform {
    let fwd = -cam.view.w;
    let rot = Quat::from_rotation_arc(Vec3::Z, -fwd);
    Transform::from_affine(&Affine3A::from_rotation_translation(rot, cam.view.eye + fwd))
}

#[test]
fn zero_layers_is_an_error() {
    let (s, _) = glass_scene();
    let e = render_depth_peeling(&s, &top_camera(), &mut frame(), 0, &unlit()).unwrap_err();
    assert!(matches!(e, Error::InvalidOptions(_)), "{e}");
    assert!(e.to_string().contains("at least 1 layer"), "{e}");
}

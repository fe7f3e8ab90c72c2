//! The look of pictures: the sky, emitted light and supersampling change colours only. With
//! the pictures' shading the rasterizer and the ray caster still draw the same triangle IDs
//! and depth as without it, paint the same sky on the background, and the lit windows of the
//! city are brighter than the dark ones on every side.

use glam::Vec3;
use sightline_render::{aa, draw_all, Framebuffer, RayCaster, RaycastOptions, RenderOptions, Renderer, ShadeOptions};
use sightline_scene::path::CameraKey;
use sightline_scene::Camera;

use crate::support::small_city;

fn street_camera(aspect: f32) -> Camera {
    let key = CameraKey {
        eye: [26.0, 1.7, 60.0],
        target: [26.0, 6.0, -60.0],
        up: [0.0, 1.0, 0.0],
        fovy_deg: 60.0,
        near: 0.1,
        far: 2000.0,
    };
    key.camera(aspect).unwrap()
}

fn raster(scene: &sightline_scene::Scene, camera: &Camera, opts: &RenderOptions, w: u32, h: u32) -> Framebuffer {
    let instances = scene.instances();
    let mut fb = Framebuffer::new(w, h).unwrap();
    Renderer::new().render(scene, &instances, &draw_all(&instances), camera, &mut fb, opts).unwrap();
    fb
}

#[test]
fn the_sky_and_the_light_change_colours_only_and_both_renderers_paint_the_same_sky() {
    let city = small_city();
    let (w, h) = (96, 64);
    let camera = street_camera(w as f32 / h as f32);
    let plain = RenderOptions::default();
    let picture = RenderOptions { shading: ShadeOptions::picture(), ..RenderOptions::default() };
    let (a, b) = (raster(&city.scene, &camera, &plain, w, h), raster(&city.scene, &camera, &picture, w, h));
    assert_eq!(a.ids, b.ids);
    assert_eq!(a.depth, b.depth);
    assert!(a.ids.contains(&0) && a.ids.iter().any(|&i| i != 0), "the view shows sky and city");
    // Background: the flat clear colour without the sky, the row's sky colour with it.
    let sky = ShadeOptions::picture().sky.unwrap().rows(&camera, h as usize);
    for (i, &id) in b.ids.iter().enumerate() {
        if id == 0 {
            assert_eq!(a.color[i], plain.background);
            assert_eq!(b.color[i], sky[i / w as usize], "pixel {i}");
        }
    }
    let caster = RayCaster::build(&city.scene).unwrap();
    let mut r = Framebuffer::new(w, h).unwrap();
    caster.render(&city.scene, &camera, &mut r, &RaycastOptions::from_render(&picture)).unwrap();
    let both_background: Vec<usize> = (0..r.len()).filter(|&i| r.ids[i] == 0 && b.ids[i] == 0).collect();
    assert!(!both_background.is_empty());
    assert!(both_background.iter().all(|&i| r.color[i] == b.color[i]), "the ray caster paints the rasterizer's sky");
    // Where both see the same triangle, both shade it alike: the ray caster's frame is
    // shaded from its IDs by the rasterizer's own pass.
    let same = (0..r.len()).filter(|&i| r.ids[i] != 0 && r.ids[i] == b.ids[i]);
    assert!(same.clone().count() > 0);
    let differ = same.filter(|&i| r.color[i] != b.color[i]).count();
    assert_eq!(differ, 0, "{differ} pixels of the same triangle shaded differently");
}

#[test]
fn lit_windows_glow_on_the_shaded_side_too() {
    let city = small_city();
    let s = &city.scene;
    let by_name = |n: &str| s.materials().find(|(_, m)| m.name == n).unwrap().1.clone();
    let (dark, lit) = (by_name("window"), by_name("lit window"));
    let o = ShadeOptions::picture();
    for normal in [Vec3::X, Vec3::NEG_X, Vec3::Z, Vec3::NEG_Z] {
        let d = sightline_render::shade(&dark, normal, None, normal, 0.0, &o);
        let l = sightline_render::shade(&lit, normal, None, normal, 0.0, &o);
        assert!(l[0] as u32 > 3 * d[0] as u32 + 60, "facing {normal}: lit {l:?}, dark {d:?}");
    }
}

#[test]
fn a_supersampled_picture_keeps_the_frame_s_size_and_smooths_its_edges() {
    let city = small_city();
    let (w, h) = (96, 64);
    let camera = street_camera(w as f32 / h as f32);
    let opts = RenderOptions { shading: ShadeOptions::picture(), ..RenderOptions::default() };
    let one = raster(&city.scene, &camera, &opts, w, h);
    let sharp = aa::supersample(w, h, 2, |fb| {
        let instances = city.scene.instances();
        Renderer::new().render(&city.scene, &instances, &draw_all(&instances), &camera, fb, &opts).map(drop)
    })
    .unwrap();
    assert_eq!((sharp.width(), sharp.height()), (w, h));
    // Colours between the one-sample ones appear along edges; flat areas stay as they are.
    let mut one_colors: Vec<[u8; 4]> = one.color.to_vec();
    one_colors.sort_unstable();
    one_colors.dedup();
    let new = sharp.color.iter().filter(|c| one_colors.binary_search(c).is_err()).count();
    assert!(new > 0, "no blended edge pixel");
    let same = one.color.iter().zip(&sharp.color).filter(|(a, b)| a == b).count();
    assert!(same > one.len() / 2, "only {same} of {} pixels kept their colour", one.len());
}

//! The ray cast image does not depend on the thread count or the SIMD level: color, depth
//! and IDs are bit-identical, shaded hit by hit (shadows and CSG solids in the frame) and
//! shaded from the ID buffer (neither).

use glam::{Affine3A, Vec3};
use sightline_render::csg::{classic_demo, CsgObject};
use sightline_render::raycast::SimdLevel;
use sightline_render::{Framebuffer, RayCaster, RaycastOptions};
use sightline_scene::builders::{city, CityParams};

use crate::support::assert_bit_identical;

fn frame(
    caster: &RayCaster,
    scene: &sightline_scene::Scene,
    cam: &sightline_scene::Camera,
    opts: &RaycastOptions,
    threads: usize,
) -> Framebuffer {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let mut fb = Framebuffer::new(203, 117).unwrap();
    // Junk where a frame must write every pixel (IDs, depth and color): a pixel the ray
    // caster skipped would keep it and differ from the reference, which starts cleared.
    if threads > 1 {
        fb.ids.fill(0xDEAD_BEEF);
        fb.depth.fill(-7.0);
        fb.color.fill([1, 2, 3, 4]);
    }
    pool.install(|| caster.render(scene, cam, &mut fb, opts)).unwrap();
    fb
}

#[test]
fn raycast_is_deterministic_across_threads_and_simd_levels() {
    let c = city(&CityParams::for_triangles(20_000)).unwrap();
    let b = c.layout.bounds();
    let solid = CsgObject::new(
        "demo",
        &classic_demo(),
        Affine3A::from_scale_rotation_translation(Vec3::splat(12.0), glam::Quat::IDENTITY, b.center() + Vec3::Y * 30.0),
        [0.9, 0.5, 0.2, 1.0],
    )
    .unwrap();
    let plain = RayCaster::build(&c.scene).unwrap();
    let with_csg = RayCaster::build(&c.scene).unwrap().with_csg(vec![solid]);
    let aspect = 203.0 / 117.0;
    let cams =
        [c.layout.street_path(20, 1)[5].camera(aspect).unwrap(), c.layout.aerial_path(8)[3].camera(aspect).unwrap()];
    let per_hit = RaycastOptions { shadows: true, ..RaycastOptions::default() };
    for (caster, opts) in [(&with_csg, per_hit), (&plain, RaycastOptions::default())] {
        for cam in &cams {
            let reference = frame(caster, &c.scene, cam, &RaycastOptions { simd: SimdLevel::Portable, ..opts }, 1);
            assert!(reference.ids.iter().any(|&i| i != 0));
            for simd in [SimdLevel::Portable, SimdLevel::Avx2, SimdLevel::Avx512, SimdLevel::Auto] {
                for threads in [1, 2, 3] {
                    let f = frame(caster, &c.scene, cam, &RaycastOptions { simd, ..opts }, threads);
                    let what = format!("{simd:?} with {threads} threads, shadows {}", opts.shadows);
                    assert_bit_identical(&reference, &f, &what);
                }
            }
        }
    }
}

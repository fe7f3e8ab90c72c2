//! Culling is exactly conservative: with every culling method the triangle-ID buffer equals
//! the brute-force one, on many cameras, for the instanced city, for the same city loaded
//! back as one big OBJ mesh, and for a glTF scene.

use sightline::render::{compare_ids, Culler, Framebuffer, Method, RenderOptions, Renderer};
use sightline::scene::builders::{city, CityParams};
use sightline::scene::path::CameraKey;
use sightline::scene::Scene;

use crate::support::camera_key;

const W: u32 = 320;
const H: u32 = 180;

/// Renders every camera with every method and checks the IDs against brute force.
/// Returns per-method triangles drawn, summed over the street cameras.
fn check(scene: &Scene, keys: &[CameraKey], what: &str) -> [u64; Method::ALL.len()] {
    check_with(scene, keys, what, &RenderOptions::ids_only())
}

fn check_with(scene: &Scene, keys: &[CameraKey], what: &str, opts: &RenderOptions) -> [u64; Method::ALL.len()] {
    let mut culler = Culler::new(scene);
    let opts = *opts;
    let mut reference = Framebuffer::new(W, H).unwrap();
    let mut fb = Framebuffer::new(W, H).unwrap();
    let mut drawn = [0u64; Method::ALL.len()];
    let mut seeing = 0;
    for (k, key) in keys.iter().enumerate() {
        let cam = key.camera(W as f32 / H as f32).unwrap();
        culler.render(scene, &cam, Method::Brute, &mut reference, &opts).unwrap();
        seeing += reference.ids.iter().any(|&i| i != 0) as usize;
        for (m, method) in Method::ALL.iter().enumerate() {
            let (cs, _) = culler.render(scene, &cam, *method, &mut fb, &opts).unwrap();
            drawn[m] += cs.triangles_drawn;
            if let Some(mm) = compare_ids(&reference.ids, &fb.ids, W) {
                panic!("{what}, camera {k}, {}: {mm:?}", method.name());
            }
        }
    }
    // A test on empty images would prove nothing.
    assert!(seeing * 4 >= keys.len() * 3, "{what}: only {seeing} of {} cameras see anything", keys.len());
    drawn
}

fn small_city() -> sightline::scene::builders::City {
    city(&CityParams::for_triangles(200_000)).unwrap()
}

#[test]
fn culled_city_equals_brute_force_on_street_and_aerial_cameras() {
    let c = small_city();
    let street = c.layout.street_path(16, 3);
    let drawn = check(&c.scene, &street, "street");
    // Occlusion culling pays off at street level.
    assert!(drawn[2] * 4 < drawn[1], "hzb drew {} triangles, frustum {}", drawn[2], drawn[1]);
    assert!(drawn[3] < drawn[1], "octree-hzb drew {} triangles, frustum {}", drawn[3], drawn[1]);
    assert!(drawn[4] * 4 < drawn[1], "hzb-one-pass drew {} triangles, frustum {}", drawn[4], drawn[1]);
    let aerial = c.layout.aerial_path(8);
    check(&c.scene, &aerial, "aerial");
}

#[test]
fn culled_city_from_one_obj_mesh_equals_brute_force() {
    let c = small_city();
    let flat = as_one_mesh(&c.scene, "near");
    let street = c.layout.street_path(12, 5);
    let drawn = check(&flat, &street, "obj street");
    // Clusters carry the culling when there is no instance structure.
    assert!(drawn[2] * 4 < drawn[1], "hzb drew {} triangles, frustum {}", drawn[2], drawn[1]);
    check(&flat, &c.layout.aerial_path(4), "obj aerial");
    let mut u16_opts = RenderOptions::ids_only();
    u16_opts.depth_format = sightline::render::DepthFormat::Unorm16;
    check_with(&flat, &street[..6], "obj street, 16-bit depth", &u16_opts);
}

/// `scene` exported to one OBJ mesh in world coordinates and loaded back (through a
/// temporary folder named with `tag`).
fn as_one_mesh(scene: &Scene, tag: &str) -> Scene {
    let dir = std::env::temp_dir().join(format!("sightline-culling-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = dir.join("city.obj");
    sightline::scene::export::export_obj(scene, &obj).unwrap();
    let flat = sightline::scene::load(&obj).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(flat.stats().instances, 1);
    flat
}

#[test]
fn culled_gltf_scene_equals_brute_force() {
    let scene = sightline::scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/nested.gltf")).unwrap();
    let b = scene.world_aabb();
    let c = b.center();
    let r = b.extent().length();
    let keys: Vec<CameraKey> = (0..8)
        .map(|i| {
            let a = i as f32 * std::f32::consts::TAU / 8.0;
            camera_key([c.x + r * a.cos(), c.y + 0.3 * r, c.z + r * a.sin()], c.into(), 50.0, 0.01, 10.0 * r)
        })
        .collect();
    // Its triangles are one-sided: look at both sides, shaded, to cover that path too.
    let opts = RenderOptions { backface_culling: false, ..Default::default() };
    check_with(&scene, &keys, "gltf", &opts);
    for depth_format in [sightline::render::DepthFormat::Unorm16, sightline::render::DepthFormat::Unorm24] {
        check_with(&scene, &keys, &format!("gltf, {depth_format:?}"), &RenderOptions { depth_format, ..opts });
    }
}

/// The city moved 30 km from the world's origin, where f32 world coordinates keep only
/// about 2 mm: box tests must allow for the rounding of projecting such coordinates (boxes
/// are projected from the eye, and their margins follow the distances involved), both for
/// the instanced city and for the same city as one mesh in world coordinates, whose
/// vertices round as coarsely as the boxes would. (These cameras did not catch the fixed
/// 10^-6 margin this replaced; the projector's own tests do.)
#[test]
fn culled_city_far_from_the_origin_equals_brute_force() {
    use sightline::scene::{Keep, NodeDesc, Transform};
    let mut c = small_city();
    let offset = glam::Vec3::new(30_000.0, 0.0, -30_000.0);
    let roots: Vec<_> = c.scene.roots().collect();
    let far = c.scene.add_node(None, NodeDesc::new("far").transform(Transform::from_translation(offset))).unwrap();
    for r in roots {
        c.scene.set_parent(r, Some(far), Keep::Local).unwrap();
    }
    c.scene.update_transforms();
    let moved = |keys: Vec<CameraKey>| -> Vec<CameraKey> {
        let shift = |p: [f32; 3]| (glam::Vec3::from(p) + offset).into();
        keys.into_iter().map(|k| CameraKey { eye: shift(k.eye), target: shift(k.target), ..k }).collect()
    };
    let street = moved(c.layout.street_path(12, 7));
    let drawn = check(&c.scene, &street, "far street");
    assert!(drawn[2] * 4 < drawn[1], "hzb drew {} triangles, frustum {}", drawn[2], drawn[1]);
    check(&c.scene, &moved(c.layout.aerial_path(4)), "far aerial");
    let flat = as_one_mesh(&c.scene, "far");
    let drawn = check(&flat, &street, "far obj street");
    assert!(drawn[2] * 4 < drawn[1], "hzb drew {} triangles, frustum {}", drawn[2], drawn[1]);
}

/// Frames overwrite every plane, so nothing of the previous contents of the target (here
/// garbage) shows through, whatever the method: colors, depths, IDs and depth-test counts
/// equal those of a brand-new framebuffer.
#[test]
fn frames_need_no_clear() {
    let c = city(&CityParams::for_triangles(30_000)).unwrap();
    let cam = c.layout.street_path(10, 3)[4].camera(W as f32 / H as f32).unwrap();
    let mut culler = Culler::new(&c.scene);
    let opts = RenderOptions::default();
    let garbage = |fb: &mut Framebuffer| {
        fb.color.fill([1, 2, 3, 4]);
        fb.depth.fill(0.25);
        fb.ids.fill(77);
        if let Some(d) = &mut fb.depth_tests {
            d.fill(9);
        }
    };
    for method in Method::ALL {
        for counting in [false, true] {
            let mut clean = Framebuffer::new(W, H).unwrap();
            let mut dirty = Framebuffer::new(W, H).unwrap();
            clean.count_depth_tests(counting);
            dirty.count_depth_tests(counting);
            garbage(&mut dirty);
            culler.render(&c.scene, &cam, method, &mut clean, &opts).unwrap();
            culler.render(&c.scene, &cam, method, &mut dirty, &opts).unwrap();
            let what = format!("{}, counting {counting}", method.name());
            assert!(clean.ids.contains(&0) && clean.ids.iter().any(|&i| i != 0), "{what}");
            assert_eq!(clean.ids, dirty.ids, "{what}");
            assert_eq!(clean.depth, dirty.depth, "{what}");
            assert_eq!(clean.color, dirty.color, "{what}");
            assert_eq!(clean.depth_tests, dirty.depth_tests, "{what}");
        }
    }
}

/// `hzb` starts from the last frame's visible set; camera cuts (street and aerial views
/// alternating, the path walked backwards) must not cost exactness.
#[test]
fn hzb_after_camera_cuts_equals_brute_force() {
    let c = city(&CityParams::for_triangles(100_000)).unwrap();
    let mut keys: Vec<CameraKey> = Vec::new();
    for (s, a) in c.layout.street_path(10, 3).into_iter().rev().zip(c.layout.aerial_path(10)) {
        keys.push(s);
        keys.push(a);
    }
    let mut culler = Culler::new(&c.scene);
    let opts = RenderOptions::ids_only();
    let (mut reference, mut fb) = (Framebuffer::new(W, H).unwrap(), Framebuffer::new(W, H).unwrap());
    for (k, key) in keys.iter().enumerate() {
        let cam = key.camera(W as f32 / H as f32).unwrap();
        culler.render(&c.scene, &cam, Method::Brute, &mut reference, &opts).unwrap();
        culler.render(&c.scene, &cam, Method::Hzb, &mut fb, &opts).unwrap();
        if let Some(mm) = compare_ids(&reference.ids, &fb.ids, W) {
            panic!("camera {k}: {mm:?}");
        }
    }
}

/// Integer depth buffers round depths to a grid, so far surfaces tie often; ties go to the
/// smaller triangle ID, which coarse depth must respect: every method still equals brute
/// force with 16- and 24-bit depth.
#[test]
fn culled_city_with_integer_depth_equals_brute_force() {
    let c = city(&CityParams::for_triangles(100_000)).unwrap();
    let street = c.layout.street_path(12, 5);
    for fmt in [sightline::render::DepthFormat::Unorm16, sightline::render::DepthFormat::Unorm24] {
        let mut opts = RenderOptions::ids_only();
        opts.depth_format = fmt;
        check_with(&c.scene, &street, &format!("{fmt:?}"), &opts);
    }
}

/// `Culler::draw_clusters` draws what the culling methods draw: every cluster, in any order
/// and in several batches of one session, gives brute force's IDs; a part of the clusters
/// gives only their triangles; a cluster the culler does not have is an error naming it.
#[test]
fn drawing_the_culler_s_clusters_yourself_equals_brute_force() {
    let c = city(&CityParams::for_triangles(50_000)).unwrap();
    let mut culler = Culler::new(&c.scene);
    let opts = RenderOptions::ids_only();
    let mut renderer = Renderer::new();
    let (mut reference, mut fb) = (Framebuffer::new(W, H).unwrap(), Framebuffer::new(W, H).unwrap());
    let n = culler.clustered().item_count() as u32;
    // Farthest-first by index, in three batches.
    let every: Vec<u32> = (0..n).rev().collect();
    let part: Vec<u32> = (0..n).filter(|i| i % 3 == 0).collect();
    let mut brute = Culler::new(&c.scene);
    for key in c.layout.street_path(6, 3) {
        let cam = key.camera(W as f32 / H as f32).unwrap();
        brute.render(&c.scene, &cam, Method::Brute, &mut reference, &opts).unwrap();
        let mut s = renderer.begin(&mut fb, &opts);
        for batch in every.chunks(every.len() / 3 + 1) {
            culler.draw_clusters(&mut s, batch, &cam).unwrap();
        }
        s.finish();
        if let Some(mm) = compare_ids(&reference.ids, &fb.ids, W) {
            panic!("every cluster: {mm:?}");
        }
        let mut s = renderer.begin(&mut fb, &opts);
        culler.draw_clusters(&mut s, &part, &cam).unwrap();
        s.finish();
        // The triangle IDs the part may show: 1 + instance's first triangle + mesh triangle.
        let instances = culler.instances();
        let mut allowed: Vec<u32> = part
            .iter()
            .flat_map(|&i| {
                let first = instances[culler.clustered().item(i).instance as usize].first_triangle;
                culler.clustered().triangles(i).iter().map(move |&t| first + t + 1)
            })
            .collect();
        allowed.sort_unstable();
        let shown: Vec<u32> = fb.ids.iter().copied().filter(|&id| id != 0).collect();
        assert!(!shown.is_empty(), "the part shows nothing");
        assert!(shown.iter().all(|id| allowed.binary_search(id).is_ok()), "a triangle outside the part was drawn");
    }
    // After the buildings move (and the culler syncs), the clusters are drawn where they are.
    let mut scene = c.scene;
    let shift = glam::Affine3A::from_translation(glam::Vec3::new(1.5, 0.0, 0.5));
    for inst in scene.instances() {
        // world' = shift · world: the local matrix becomes parent⁻¹ · shift · parent · local.
        let local = scene.node(inst.node).unwrap().local_matrix();
        let parent = inst.world_from_local * local.inverse();
        scene.set_local_matrix(inst.node, parent.inverse() * shift * parent * local).unwrap();
    }
    scene.update_transforms();
    culler.sync(&scene).unwrap();
    let cam = c.layout.street_path(1, 3)[0].camera(W as f32 / H as f32).unwrap();
    brute.render(&scene, &cam, Method::Brute, &mut reference, &opts).unwrap();
    let mut s = renderer.begin(&mut fb, &opts);
    culler.draw_clusters(&mut s, &every, &cam).unwrap();
    s.finish();
    if let Some(mm) = compare_ids(&reference.ids, &fb.ids, W) {
        panic!("moved: {mm:?}");
    }
    let mut s = renderer.begin(&mut fb, &opts);
    let err = culler.draw_clusters(&mut s, &[0, n], &cam).unwrap_err().to_string();
    assert!(err.contains(&format!("cluster {n}")) && err.contains(&format!("{n} clusters")), "{err}");
}

//! The ray caster draws what the rasterizer draws: triangle IDs agree on ≥ 99.5% of the
//! pixels and depths within 1e-5 where they agree, for several cameras on a city, on the
//! glTF asset and on a scene of intersecting triangles. Where the IDs agree the colors are
//! the same: exactly, when the ray caster shades its frame with the rasterizer's deferred
//! pass; within 2 levels when it shades each hit itself (with shadows), from the hit's
//! exact barycentrics.

use glam::{Quat, Vec3};
use sightline_render::{render_scene, Framebuffer, RayCaster, RaycastOptions, RenderOptions};
use sightline_scene::{Angle, Camera, LookAt, Mesh, NodeDesc, Projection, Scene, Transform, View};

use crate::support::small_city;

const W: u32 = 192;
const H: u32 = 108;

/// Agreement of a rasterized and a ray cast frame.
struct Agreement {
    /// Fraction of pixels with equal IDs.
    ids: f64,
    /// Fraction of pixels with equal, non-background IDs whose depths differ by ≤ 1e-5.
    depth_close: f64,
    /// Largest depth difference on those pixels.
    depth_max: f32,
    /// Pixels the ray caster hit.
    hits: usize,
    /// Fraction of pixels with equal, non-background IDs whose colors differ by at most
    /// `tolerance` per channel.
    color_close: f64,
}

/// How the ray caster colors its frame in a comparison.
#[derive(Clone, Copy, PartialEq)]
enum Colors {
    /// With the rasterizer's deferred pass over its IDs (no shadows): the same colors.
    FromIds,
    /// Hit by hit (shadows on, with nothing to cast them): the same shading function at
    /// exact rather than interpolated barycentrics, so within 2 levels.
    PerHit,
}

fn compare(scene: &Scene, camera: &Camera, opts: &RenderOptions, colors: Colors) -> Agreement {
    let mut a = Framebuffer::new(W, H).unwrap();
    render_scene(scene, camera, &mut a, opts).unwrap();
    let caster = RayCaster::build(scene).unwrap();
    let mut b = Framebuffer::new(W, H).unwrap();
    let ro = RaycastOptions { shadows: colors == Colors::PerHit, ..RaycastOptions::from_render(opts) };
    caster.render(scene, camera, &mut b, &ro).unwrap();
    let tolerance = if colors == Colors::PerHit { 2 } else { 0 };
    let (mut same, mut both, mut close, mut color_close) = (0usize, 0usize, 0usize, 0usize);
    let mut depth_max = 0f32;
    for i in 0..a.len() {
        if a.ids[i] == b.ids[i] {
            same += 1;
            if a.ids[i] != 0 {
                both += 1;
                let err = (a.depth[i] - b.depth[i]).abs();
                close += (err <= 1e-5) as usize;
                color_close += a.color[i].iter().zip(&b.color[i]).all(|(x, y)| x.abs_diff(*y) <= tolerance) as usize;
                depth_max = depth_max.max(err);
            }
        }
    }
    Agreement {
        ids: same as f64 / a.len() as f64,
        depth_close: close as f64 / both.max(1) as f64,
        depth_max,
        hits: b.ids.iter().filter(|&&i| i != 0).count(),
        color_close: color_close as f64 / both.max(1) as f64,
    }
}

/// IDs agree on ≥ 99.5% of the pixels; depths agree within 1e-5 on ≥ 99% of the pixels
/// where the IDs agree. (The rest are sliver triangles seen edge-on, a pixel or so wide,
/// where the rasterizer's 1/256-pixel vertex snapping tilts the depth plane; the ray
/// caster's depth matches an exact f64 reference there, see `raycast_reference.rs`.)
/// Colors agree on every such pixel when shaded from the IDs, on ≥ 99% within 2 levels
/// when shaded per hit.
fn check(name: &str, scene: &Scene, camera: &Camera, opts: &RenderOptions) {
    check_colored(name, scene, camera, opts, Colors::FromIds);
}

fn check_colored(name: &str, scene: &Scene, camera: &Camera, opts: &RenderOptions, colors: Colors) {
    let r = compare(scene, camera, opts, colors);
    eprintln!(
        "{name}: IDs agree on {:.3}% of pixels; depth within 1e-5 on {:.3}% of them (max diff {:e}), colors alike on {:.3}%; {} hit pixels",
        r.ids * 100.0,
        r.depth_close * 100.0,
        r.depth_max,
        r.color_close * 100.0,
        r.hits
    );
    assert!(r.hits > 0, "{name}: nothing visible, the test proves nothing");
    assert!(r.ids >= 0.995, "{name}: only {:.3}% of the IDs agree", r.ids * 100.0);
    assert!(r.depth_close >= 0.99, "{name}: depth within 1e-5 on only {:.3}%", r.depth_close * 100.0);
    let needed = if colors == Colors::FromIds { 1.0 } else { 0.99 };
    assert!(r.color_close >= needed, "{name}: colors agree on only {:.3}%", r.color_close * 100.0);
}

#[test]
fn raycast_city_from_the_street_and_the_air() {
    let c = small_city();
    let aspect = W as f32 / H as f32;
    let opts = RenderOptions::default();
    let street = c.layout.street_path(40, 3);
    let aerial = c.layout.aerial_path(12);
    for (k, key) in [street[0], street[17], street[33], aerial[0], aerial[7]].iter().enumerate() {
        check(&format!("city camera {k}"), &c.scene, &key.camera(aspect).unwrap(), &opts);
    }
    // Back-face culling off.
    let no_cull = RenderOptions { backface_culling: false, ..RenderOptions::default() };
    check("city, no culling", &c.scene, &aerial[3].camera(aspect).unwrap(), &no_cull);
}

#[test]
fn raycast_city_through_parallel_projections() {
    let c = small_city();
    let b = c.layout.bounds();
    let center = b.center();
    let view = View::look_at(center + Vec3::new(150.0, 200.0, 120.0), center, Vec3::Y).unwrap();
    let r = b.extent().length() * 0.4;
    let ortho = Projection::orthographic(-r, r, -r * 0.5625, r * 0.5625, 1.0, 1000.0).unwrap();
    let cab = Projection::cabinet(-r, r, -r * 0.5625, r * 0.5625, 1.0, 1000.0, 0.5).unwrap();
    for (name, p) in [("orthographic", ortho), ("cabinet", cab)] {
        check(name, &c.scene, &Camera::new(view, p).unwrap(), &RenderOptions::default());
    }
}

#[test]
fn raycast_gltf_asset() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/nested.gltf");
    let scene = sightline_scene::load(path).unwrap();
    let b = scene.world_aabb();
    let c = b.center();
    let r = b.extent().length().max(1e-3);
    let aspect = W as f32 / H as f32;
    let both_sides = RenderOptions { backface_culling: false, ..RenderOptions::default() };
    for (k, dir) in [Vec3::new(1.0, 0.8, 1.3), Vec3::new(-1.2, 0.4, 0.7), Vec3::new(0.3, -1.0, -0.9)].iter().enumerate()
    {
        let cam = Camera::perspective(
            &LookAt {
                eye: c + dir.normalize() * r * 1.2,
                target: c,
                up: Vec3::Y,
                fovy: Angle::degrees(50.0),
                near: r * 0.01,
                far: r * 10.0,
            },
            aspect,
        )
        .unwrap();
        if k < 2 {
            // (From below, the single-sided triangles all face away.)
            check(&format!("nested.gltf camera {k}"), &scene, &cam, &RenderOptions::default());
        }
        check(&format!("nested.gltf camera {k}, both sides"), &scene, &cam, &both_sides);
    }
    // The camera the file brings (a node with a perspective projection).
    let sc = &scene.cameras[0];
    let m = scene.node(sc.node).unwrap().world_matrix();
    let eye = Vec3::from(m.translation);
    let view = View::look_along(eye, -Vec3::from(m.matrix3.z_axis), Vec3::from(m.matrix3.y_axis)).unwrap();
    let own = Camera::new(view, sc.projection).unwrap();
    check("nested.gltf's own camera", &scene, &own, &both_sides);
    // Per-pixel lighting with the textured quad.
    let mut per_pixel = both_sides;
    per_pixel.shading.mode = sightline_render::ShadingMode::PerPixel;
    check("nested.gltf's own camera, per-pixel shading", &scene, &own, &per_pixel);
}

#[test]
fn raycast_intersecting_triangles() {
    // Large triangles piercing each other at many angles: visibility changes along the
    // intersection lines, where the two renderers must pick the same triangle.
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    let mut rng = 12345u64;
    let mut next = || {
        rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((rng >> 33) as f32 / (1u64 << 31) as f32) * 2.0 - 1.0
    };
    for _ in 0..60 {
        let c = Vec3::new(next(), next(), next()) * 2.0;
        for _ in 0..3 {
            positions.push(c + Vec3::new(next(), next(), next()) * 2.5);
        }
        let n = positions.len() as u32;
        indices.extend_from_slice(&[n - 3, n - 2, n - 1]);
    }
    let mut scene = Scene::new();
    let m = scene.add_mesh(Mesh::new("shards", positions, None, None, indices).unwrap());
    scene.add_node(None, NodeDesc::new("shards").mesh(m)).unwrap();
    let t = Transform::from_translation(Vec3::new(0.5, 0.0, -1.0)).with_rotation(Quat::from_rotation_y(0.7));
    scene.add_node(None, NodeDesc::new("shards 2").transform(t).mesh(m)).unwrap();
    scene.update_transforms();
    let aspect = W as f32 / H as f32;
    let opts = RenderOptions { backface_culling: false, ..RenderOptions::default() };
    for (k, eye) in [Vec3::new(0.0, 1.0, 9.0), Vec3::new(7.0, -3.0, 4.0)].iter().enumerate() {
        let cam = Camera::perspective(
            &LookAt { eye: *eye, target: Vec3::ZERO, up: Vec3::Y, fovy: Angle::degrees(60.0), near: 0.1, far: 50.0 },
            aspect,
        )
        .unwrap();
        check(&format!("intersecting triangles {k}"), &scene, &cam, &opts);
    }
}

/// A smooth-shaded hill whose squares are split `(a, b, c)`, `(c, d, a)`, as many exporters
/// write them: the ray caster stores each pair as a quad with the second triangle turned,
/// and still shades with the mesh's vertex order (Gouraud and per-pixel colors agree with
/// the rasterizer's), and a hit's barycentric weights are those of the mesh's vertices.
/// The same with the hill's triangles shuffled, so that no two halves of a square are
/// neighbours in the mesh: they pair across their shared edge all the same.
#[test]
fn raycast_turned_quads_shade_in_mesh_order() {
    for shuffled in [false, true] {
        turned_quads_shade_in_mesh_order(shuffled);
    }
}

fn turned_quads_shade_in_mesh_order(shuffled: bool) {
    const N: u32 = 24;
    let height = |x: f32, z: f32| (x * 0.7).sin() * (z * 0.5).cos();
    let (mut positions, mut normals, mut indices) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..=N {
        for i in 0..=N {
            let (x, z) = (i as f32 * 0.5 - 6.0, j as f32 * 0.5 - 6.0);
            positions.push(Vec3::new(x, height(x, z), z));
            // Normals far from the faces' own: weights in the wrong order show.
            normals.push(Vec3::new((z * 1.3).sin(), 1.0, (x * 1.1).cos()).normalize());
        }
    }
    let v = |i: u32, j: u32| j * (N + 1) + i;
    for j in 0..N {
        for i in 0..N {
            let (a, b, c, d) = (v(i, j), v(i, j + 1), v(i + 1, j + 1), v(i + 1, j));
            indices.extend_from_slice(&[a, b, c, c, d, a]);
        }
    }
    if shuffled {
        // Triangle t goes to place 7t + 3 (mod 2N², which 7 does not divide).
        let n = indices.len() / 3;
        let mut moved = vec![0; indices.len()];
        for t in 0..n {
            let to = (7 * t + 3) % n;
            moved[3 * to..3 * to + 3].copy_from_slice(&indices[3 * t..3 * t + 3]);
        }
        indices = moved;
    }
    let mut scene = Scene::new();
    let m = scene.add_mesh(Mesh::new("hill", positions, Some(normals), None, indices).unwrap());
    scene.add_node(None, NodeDesc::new("hill").mesh(m)).unwrap();
    scene.update_transforms();
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(4.0, 6.0, 9.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 50.0,
        },
        W as f32 / H as f32,
    )
    .unwrap();
    for mode in [sightline_render::ShadingMode::Gouraud, sightline_render::ShadingMode::PerPixel] {
        let mut opts = RenderOptions::default();
        opts.shading.mode = mode;
        check(&format!("turned quads (shuffled: {shuffled}), {mode:?}"), &scene, &cam, &opts);
        // Shaded hit by hit, from the quads' weights put back in mesh order: with the light
        // straight above, a heightfield casts no shadow on itself, so only the weights
        // (exact against interpolated) tell the two frames apart.
        opts.shading.light_dir = Vec3::Y;
        let name = format!("turned quads (shuffled: {shuffled}), {mode:?}, shaded per hit");
        check_colored(&name, &scene, &cam, &opts, Colors::PerHit);
    }
    let caster = RayCaster::build(&scene).unwrap();
    assert_eq!(caster.paired_triangles(), (2 * N * N) as usize, "shuffled: {shuffled}");
    let mesh = scene.mesh(m).unwrap();
    let blas = sightline_spatial::bvh::wide::WideBlas::from_mesh(mesh);
    let sightline_spatial::bvh::wide::BlasPrims::Quads(quads) = blas.prims() else { panic!("the hill pairs up") };
    assert!(quads.iter().all(|q| q.is_pair()), "shuffled: {shuffled}");
    let mut turned = 0;
    for k in 0..40 {
        let target = Vec3::new(k as f32 * 0.27 - 5.0, 0.0, (k as f32 * 0.61).sin() * 4.0);
        let (origin, dir) = (Vec3::new(target.x, 5.0, target.z), -Vec3::Y);
        let hit = caster.intersect(origin, dir, 0.0, 100.0).expect("the ray meets the hill");
        let sightline_render::raycast::HitTarget::Triangle { triangle, barycentric: b, .. } = hit.target else {
            panic!("a mesh triangle was hit")
        };
        let [p0, p1, p2] = mesh.triangle_positions(triangle as usize);
        let at = p0 + (p1 - p0) * b.x + (p2 - p0) * b.y;
        let p = origin + dir * hit.t;
        assert!(at.distance(p) < 1e-4, "ray {k}: the weights give {at}, the hit is at {p}");
        // The second triangle of each square, `(c, d, a)` with c = a + N + 2, is turned.
        let t = &mesh.indices()[3 * triangle as usize..][..3];
        turned += (t[0] == t[2] + N + 2) as u32;
    }
    assert!(turned > 0, "some rays must hit the turned halves");
}

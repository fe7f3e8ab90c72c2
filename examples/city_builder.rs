//! Building a larger scene in code with the public API (`use sightline::prelude::*`): a city,
//! a few thousand props sharing one mesh, a glTF model loaded once and placed a thousand
//! times, then one frame to PNG and the scene's statistics.
//!
//! ```sh
//! cargo run --release --example city_builder -- --out city-builder-out
//! ```
//!
//! Meshes are stored once and drawn many times: the props are instances of one cube, and the
//! model's meshes are added to the scene once by `load_prefab`, each placement adding only
//! nodes. `World` builds the culling structures on the first frame.

use std::path::PathBuf;

use sightline::prelude::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = match std::env::args().skip(1).collect::<Vec<_>>().as_slice() {
        [] => PathBuf::from("city-builder-out"),
        [flag, dir] if flag == "--out" || flag == "-o" => PathBuf::from(dir),
        _ => return Err("usage: city_builder [--out DIR]".into()),
    };
    std::fs::create_dir_all(&out)?;

    // A city of about 300,000 triangles: blocks of instanced buildings on a ground grid.
    let city = city(&CityParams::for_triangles(300_000))?;
    let (mut scene, streets) = (city.scene, city.layout.bounds());

    // 3,000 crates scattered over the streets and yards, all one mesh.
    let crate_mesh = scene.add_mesh(shapes::cube("crate")?);
    let yard = Aabb::new(Vec3::new(streets.min.x, 0.5, streets.min.z), Vec3::new(streets.max.x, 0.5, streets.max.z));
    let params = ScatterParams { count: 3000, region: yard, scale: (0.6, 1.6), upright: true, seed: 7 };
    scatter(&mut scene, None, "crates", crate_mesh, &params)?;

    // A glTF model, loaded once, placed a thousand times (twice its size) on a square in
    // front of the city.
    let model_path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/nested.gltf");
    let model = load_prefab(&mut scene, model_path, &LoadOptions::default())?;
    let corner = Vec3::new(streets.min.x, 0.0, streets.max.z);
    let plaza = scene.add_mesh(shapes::subdivided_box(
        "plaza",
        Vec3::new(-10.0, -0.2, 0.0),
        Vec3::new(400.0, 0.0, 260.0),
        [8, 1, 6],
        false,
    )?);
    let square =
        scene.add_node(None, NodeDesc::new("square").transform(Transform::from_translation(corner)).mesh(plaza))?;
    for i in 0..1000 {
        let at = Vec3::new((i % 40) as f32 * 10.0, 0.0, 10.0 + (i / 40) as f32 * 10.0);
        let place = Transform::from_translation(at).with_rotation(Quat::from_rotation_y(i as f32 * 0.7));
        scene.instantiate_prefab(&model, Some(square), place.with_scale(Vec3::splat(2.0)))?;
    }

    // One frame, occlusion-culled, from above the square looking into the city, to PNG.
    let mut world = World::new(scene);
    let look = LookAt {
        eye: corner + Vec3::new(-60.0, 70.0, 330.0),
        target: corner + Vec3::new(160.0, 0.0, 40.0),
        fovy: Angle::degrees(60.0),
        far: 3000.0,
        ..LookAt::default()
    };
    let camera = Camera::perspective(&look, 16.0 / 9.0)?;
    let mut fb = Framebuffer::new(1280, 720)?;
    let frame = world.render(&camera, Method::Hzb, &mut fb, &RenderOptions::default())?;
    // The picture in the sky's light, 2 × 2 samples per pixel.
    let look = RenderOptions { shading: ShadeOptions::picture(), ..RenderOptions::default() };
    let fb = aa::supersample(1280, 720, 2, |fb| world.render(&camera, Method::Frustum, fb, &look).map(drop))?;
    let picture = out.join("city.png");
    write_color_png(&fb, &picture)?;

    let s = world.scene().stats();
    println!("nodes {}, meshes {}, instances {}", s.nodes, s.meshes, s.instances);
    println!("triangles {} drawn, {} stored ({} bytes of vertices)", s.triangles, s.unique_triangles, s.vertex_bytes);
    let drawn = frame.cull.map_or(0, |c| c.triangles_drawn);
    println!("frame {:.1} ms (structures built on the way), {drawn} triangles drawn", frame.ms_total);
    println!("picture {}", picture.display());
    Ok(())
}

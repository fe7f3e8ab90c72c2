//! Loader and exporter tests: the authored assets with hand-computed world positions, and
//! small broken files written to a temporary folder, each of which must give an error (or a
//! warning) that names the file and the problem — never a panic.

use std::path::{Path, PathBuf};

use glam::{Affine3A, Quat, Vec3};
use sightline_scene::export::{export_obj, write_obj};
use sightline_scene::obj_loader::load_obj;
use sightline_scene::*;

use crate::support::{assert_mentions, asset, err_text, tmp_dir, world_triangles, TRI};

fn assert_close(got: Vec3, want: [f32; 3], what: &str) {
    let want = Vec3::from(want);
    assert!((got - want).abs().max_element() < 1e-5, "{what}: got {got}, want {want}");
}

// ---- the authored glTF --------------------------------------------------------------------

/// World positions of assets/nested.gltf, worked out by hand from the file:
///
/// root T(10,0,0) ─ arm T(0,2,0)·Rz(90°) ─┬─ scaled T(1,0,0)·S(2,3,1) [tri, red]
///                                         │    └─ leaf matrix T(0,0,5)·S(0.5) [quad: strip + fan]
///                                         └─ twin T(0,0,−1) [tri again]
///                └─ eye T(0,1,10) [camera]
///
/// Rz(90°) maps (x, y, z) to (−y, x, z).
#[test]
fn nested_gltf_world_positions_by_hand() {
    let scene = load(asset("nested.gltf")).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let names: Vec<&str> = scene.instances().iter().map(|i| scene.node(i.node).unwrap().name()).collect();
    assert_eq!(names, ["scaled", "leaf primitive 0", "leaf primitive 1", "twin"]);
    let tris = world_triangles(&scene);
    let want: [[[f32; 3]; 3]; 6] = [
        // scaled: tri (0,0,0) (1,0,0) (0,1,0) → S(2,3,1) → +(1,0,0) → Rz → +(0,2,0) → +(10,0,0)
        [[10.0, 3.0, 0.0], [10.0, 5.0, 0.0], [7.0, 3.0, 0.0]],
        // leaf strip over v0 (0,0,0) v1 (1,0,0) v2 (0,1,0) v3 (1,1,0): (v0 v1 v2), (v1 v3 v2);
        // v → ×0.5 +(0,0,5) → S(2,3,1) +(1,0,0) → Rz +(0,2,0) → +(10,0,0)
        [[10.0, 3.0, 5.0], [10.0, 4.0, 5.0], [8.5, 3.0, 5.0]],
        [[10.0, 4.0, 5.0], [8.5, 4.0, 5.0], [8.5, 3.0, 5.0]],
        // leaf fan over u8 indices 0 1 3 2: (v0 v1 v3), (v0 v3 v2)
        [[10.0, 3.0, 5.0], [10.0, 4.0, 5.0], [8.5, 4.0, 5.0]],
        [[10.0, 3.0, 5.0], [8.5, 4.0, 5.0], [8.5, 3.0, 5.0]],
        // twin: tri → +(0,0,−1) → Rz → +(0,2,0) → +(10,0,0)
        [[10.0, 2.0, -1.0], [10.0, 3.0, -1.0], [9.0, 2.0, -1.0]],
    ];
    assert_eq!(tris.len(), want.len());
    for (k, (got, want)) in tris.iter().zip(&want).enumerate() {
        for c in 0..3 {
            assert_close(got[c], want[c], &format!("triangle {k} corner {c}"));
        }
    }
    // Depth: root(0) → arm(1) → scaled(2) → leaf(3) → leaf primitive 0 (4).
    let leaf = scene.find("leaf").unwrap();
    assert_eq!(scene.node(leaf).unwrap().depth(), 3);
    // The leaf's own world matrix (its matrix composed with the TRS ancestors).
    let m = scene.node(leaf).unwrap().world_matrix();
    assert_close(m.transform_point3(Vec3::ZERO), [10.0, 3.0, 5.0], "leaf origin");
    assert_close(m.transform_vector3(Vec3::X), [0.0, 1.0, 0.0], "leaf x axis");
    assert_close(m.transform_vector3(Vec3::Y), [-1.5, 0.0, 0.0], "leaf y axis");
    assert_close(m.transform_vector3(Vec3::Z), [0.0, 0.0, 0.5], "leaf z axis");
}

#[test]
fn glb_and_embedded_gltf_equal_the_gltf() {
    let a = load(asset("nested.gltf")).unwrap();
    for other in ["nested.glb", "nested_embedded.gltf"] {
        let b = load(asset(other)).unwrap();
        assert!(b.warnings.is_empty(), "{other}: {:?}", b.warnings);
        let (ta, tb) = (world_triangles(&a), world_triangles(&b));
        assert_eq!(ta, tb, "{other}: triangles differ");
        let mats = |s: &Scene| -> Vec<Option<Material>> {
            s.instances().iter().map(|i| i.material.map(|m| s.material(m).unwrap().clone())).collect()
        };
        assert_eq!(mats(&a), mats(&b), "{other}: materials differ");
        assert_eq!(a.cameras.len(), b.cameras.len());
        assert_eq!(a.cameras[0].projection, b.cameras[0].projection);
        assert_eq!(a.node_count(), b.node_count());
        assert_eq!(a.stats().unique_triangles, b.stats().unique_triangles);
    }
}

#[test]
fn gltf_instancing_shares_one_mesh() {
    let scene = load(asset("nested.gltf")).unwrap();
    let scaled = scene.node(scene.find("scaled").unwrap()).unwrap();
    let twin = scene.node(scene.find("twin").unwrap()).unwrap();
    assert!(scaled.mesh().is_some());
    assert_eq!(scaled.mesh(), twin.mesh());
    // tri, quad strip, quad fan: three meshes for four instances.
    assert_eq!(scene.meshes().count(), 3);
    let stats = scene.stats();
    assert_eq!((stats.instances, stats.triangles), (4, 6));
    assert_eq!(stats.unique_triangles, 5);
}

#[test]
fn gltf_materials_and_texture() {
    let scene = load(asset("nested.gltf")).unwrap();
    let by_node = |name: &str| {
        let id = scene.find(name).unwrap();
        let inst = scene.instances().into_iter().find(|i| i.node == id).unwrap();
        scene.material(inst.material.unwrap()).unwrap().clone()
    };
    let red = by_node("scaled");
    assert_eq!((red.name.as_str(), red.base_color), ("red", [1.0, 0.0, 0.0, 1.0]));
    assert!(red.base_color_texture.is_none());
    assert_eq!(by_node("twin"), red);
    let checker = by_node("leaf primitive 0");
    assert_eq!(checker.name, "checker");
    assert_eq!(checker.base_color, [1.0; 4]);
    let tex = checker.base_color_texture.unwrap();
    assert_eq!((tex.width, tex.height), (8, 8));
    assert_eq!(tex.texel(0, 0), [255, 255, 255, 255]);
    assert_eq!(tex.texel(2, 0), [200, 30, 30, 255]);
    assert_eq!(tex.texel(2, 2), [255, 255, 255, 255]);
    // The fan has no material in the file. Its ancestor "scaled" draws red, but glTF has no
    // material inheritance, so it must get the default material, not red.
    let fan = by_node("leaf primitive 1");
    assert_eq!(fan, Material::default());
    // UVs come through: the tri's TEXCOORD_0.
    let scaled = scene.node(scene.find("scaled").unwrap()).unwrap();
    let mesh = scene.mesh(scaled.mesh().unwrap()).unwrap();
    assert_eq!(mesh.uvs().unwrap()[2], glam::Vec2::new(0.0, 0.0));
    assert_eq!(mesh.normals().unwrap()[0], Vec3::Z);
}

#[test]
fn gltf_camera_found() {
    let scene = load(asset("nested.gltf")).unwrap();
    assert_eq!(scene.cameras.len(), 1);
    let cam = &scene.cameras[0];
    assert_eq!(cam.name, "eye");
    let node = scene.node(cam.node).unwrap();
    assert_eq!(node.name(), "eye");
    assert_close(node.world_matrix().transform_point3(Vec3::ZERO), [10.0, 1.0, 10.0], "camera position");
    let Projection::Perspective { left, right, top, near, far, .. } = cam.projection else {
        panic!("expected a perspective camera, got {:?}", cam.projection)
    };
    let t = 0.1 * 0.4f32.tan();
    assert!((top - t).abs() < 1e-6 && (right - 1.5 * t).abs() < 1e-6 && left == -right);
    assert_eq!((near, far), (0.1, 100.0));
}

/// `Scene::camera` turns the file's camera into one for any image: placed by its node,
/// looking down the node's −z, the vertical field of view kept and the width fitted.
#[test]
fn gltf_camera_becomes_a_camera_for_any_aspect() {
    let scene = load(asset("nested.gltf")).unwrap();
    let cam = scene.camera(0, 2.0).unwrap();
    assert_close(cam.view.eye, [10.0, 1.0, 10.0], "eye");
    assert_close(cam.view.forward(), [0.0, 0.0, -1.0], "gaze");
    assert_close(cam.view.v, [0.0, 1.0, 0.0], "up");
    let Projection::Perspective { left, right, top, bottom, .. } = cam.projection else { panic!("perspective") };
    let t = 0.1 * 0.4f32.tan();
    assert!((top - t).abs() < 1e-6 && bottom == -top, "vertical extent kept: {top}");
    assert!((right - 2.0 * t).abs() < 1e-6 && left == -right, "width fitted to the aspect: {right}");
    // Out of range, and a scene without cameras: the error says how many there are.
    let e = scene.camera(1, 1.0).unwrap_err().to_string();
    assert!(e.contains("camera 1") && e.contains("1 camera"), "{e}");
    let e = Scene::new().camera(0, 1.0).unwrap_err().to_string();
    assert!(e.contains("no cameras"), "{e}");
    assert!(scene.camera(0, 0.0).is_err(), "a zero aspect is refused");
}

// ---- the authored OBJ ---------------------------------------------------------------------

#[test]
fn cube_obj_loads_with_mtl_color() {
    let scene = load(asset("cube.obj")).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let root = scene.roots().next().unwrap();
    assert_eq!(scene.node(root).unwrap().name(), "cube.obj");
    let inst = scene.instances();
    assert_eq!(inst.len(), 1);
    assert_eq!(scene.node(inst[0].node).unwrap().name(), "cube");
    assert_eq!(inst[0].triangle_count, 12);
    let mat = scene.material(inst[0].material.unwrap()).unwrap();
    assert_eq!(mat.name, "blue");
    assert_eq!(mat.base_color, [0.2, 0.4, 0.8, 1.0]);
    // First face "f 1 4 3 2" fans into (1 4 3), (1 3 2).
    let tris = world_triangles(&scene);
    let v = |x: f32, y: f32| Vec3::new(x, y, -0.5);
    assert_eq!(tris[0], [v(-0.5, -0.5), v(-0.5, 0.5), v(0.5, 0.5)]);
    assert_eq!(tris[1], [v(-0.5, -0.5), v(0.5, 0.5), v(0.5, -0.5)]);
    // Closed and outward-facing: the signed volume is +1.
    let vol: f32 = tris.iter().map(|t| t[0].dot(t[1].cross(t[2])) / 6.0).sum();
    assert!((vol - 1.0).abs() < 1e-6, "volume {vol}");
}

#[test]
fn single_object_obj_keeps_face_order() {
    let dir = tmp_dir("face-order");
    let path = dir.join("order.obj");
    // Vertices used out of order, an unused vertex, triangles, a quad, a pentagon.
    let mut text = String::from("# no o/g lines\n");
    let verts: Vec<Vec3> = (0..9).map(|i| Vec3::new(i as f32, (i * i) as f32 * 0.5, -(i as f32) * 0.25)).collect();
    for p in &verts {
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    let faces: [&[usize]; 5] = [&[5, 2, 3], &[1, 2, 3, 4], &[9, 8, 7], &[2, 4, 6, 8, 1], &[3, 1, 2]];
    let mut want = Vec::new();
    for f in faces {
        text += "f";
        for i in f {
            text += &format!(" {i}");
        }
        text += "\n";
        for k in 1..f.len() - 1 {
            want.push([f[0], f[k], f[k + 1]].map(|i| verts[i - 1]));
        }
    }
    std::fs::write(&path, text).unwrap();
    let scene = load(&path).unwrap();
    assert_eq!(scene.meshes().count(), 1, "one mesh");
    assert_eq!(world_triangles(&scene), want);
}

// ---- exporter -----------------------------------------------------------------------------

fn hierarchy_scene() -> Scene {
    let mut scene = Scene::new();
    let cube = scene.add_mesh(shapes::cube("cube").unwrap());
    let tri = scene.add_mesh(
        Mesh::new(
            "tri",
            vec![Vec3::ZERO, Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.0, 0.3, 0.7)],
            None,
            None,
            vec![0, 1, 2],
        )
        .unwrap(),
    );
    let top = scene
        .add_node(
            None,
            NodeDesc::new("top").transform(
                Transform::from_translation(Vec3::new(1.25, -3.0, 0.1)).with_rotation(Quat::from_rotation_y(0.3)),
            ),
        )
        .unwrap();
    let mid = scene
        .add_node(
            Some(top),
            NodeDesc::new("mid")
                .transform(Transform::from_scale(Vec3::new(2.0, 0.5, 1.5)).with_rotation(Quat::from_rotation_x(1.1)))
                .mesh(tri),
        )
        .unwrap();
    for i in 0..3 {
        scene
            .add_node(
                Some(mid),
                NodeDesc::new(format!("cube {i}"))
                    .transform(Transform::from_translation(Vec3::new(i as f32 * 1.7, 0.2, -0.3)))
                    .mesh(cube),
            )
            .unwrap();
    }
    scene
        .add_node(None, NodeDesc::new("far").matrix(Affine3A::from_translation(Vec3::new(1e3, 0.0, -1e-3))))
        .and_then(|n| scene.add_node(Some(n), NodeDesc::new("far cube").mesh(cube)))
        .unwrap();
    scene.update_transforms();
    scene
}

#[test]
fn export_round_trips_bitwise() {
    let scene = hierarchy_scene();
    let dir = tmp_dir("export");
    let path = dir.join("flat.obj");
    export_obj(&scene, &path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        !text.lines().any(|l| l.starts_with("o ") || l.starts_with("g ") || l.starts_with("usemtl")),
        "the export must be a single object"
    );
    let back = load_obj(&path).unwrap();
    assert!(back.warnings.is_empty(), "{:?}", back.warnings);
    assert_eq!(back.meshes().count(), 1);
    let mut back = back;
    back.update_transforms();
    let (want, got) = (world_triangles(&scene), world_triangles(&back));
    assert_eq!(want.len() as u64, scene.stats().triangles);
    assert_eq!(got.len(), want.len());
    for (k, (g, w)) in got.iter().zip(&want).enumerate() {
        for c in 0..3 {
            assert_eq!(
                g[c].to_array().map(f32::to_bits),
                w[c].to_array().map(f32::to_bits),
                "triangle {k} corner {c}: {} vs {}",
                g[c],
                w[c]
            );
        }
    }
}

#[test]
fn export_of_the_gltf_asset_matches_and_sees_unpropagated_edits() {
    let mut scene = load(asset("nested.gltf")).unwrap();
    let arm = scene.find("arm").unwrap();
    scene.set_local_transform(arm, Transform::from_translation(Vec3::new(0.0, 0.0, 3.0))).unwrap();
    // A node added and one removed, not propagated either.
    let mesh = scene.node(scene.find("twin").unwrap()).unwrap().mesh().unwrap();
    scene
        .add_node(Some(arm), NodeDesc::new("extra").mesh(mesh).transform(Transform::from_translation(Vec3::Y)))
        .unwrap();
    scene.remove_node(scene.find("leaf").unwrap()).unwrap();
    // Not propagated yet: the exporter must still use the current transforms and nodes.
    let mut bytes = Vec::new();
    write_obj(&scene, &mut bytes).unwrap();
    scene.update_transforms();
    let dir = tmp_dir("export-gltf");
    let path = dir.join("nested.obj");
    std::fs::write(&path, &bytes).unwrap();
    let mut back = load_obj(&path).unwrap();
    back.update_transforms();
    assert_eq!(world_triangles(&back), world_triangles(&scene));
}

#[test]
fn export_to_a_bad_path_names_it() {
    let scene = hierarchy_scene();
    let dir = tmp_dir("export-bad");
    let path = dir.join("no/such/dir/out.obj");
    let e = export_obj(&scene, &path).unwrap_err().to_string();
    assert_mentions(&e, &["out.obj"]);
}

// ---- broken OBJ ---------------------------------------------------------------------------

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn missing_mtl_is_a_warning() {
    let dir = tmp_dir("mtl");
    let path = write(&dir, "nomtl.obj", &format!("mtllib missing.mtl\n{TRI}usemtl red\nf 1 2 3\n"));
    let scene = load(&path).unwrap();
    assert_eq!(scene.stats().triangles, 1);
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert_mentions(&scene.warnings[0], &["nomtl.obj", "missing.mtl", "file not found"]);
    assert_eq!(scene.instances()[0].material, None, "default material");
}

#[test]
fn broken_mtl_lines_and_textures_are_warnings() {
    let dir = tmp_dir("mtl-bad");
    write(&dir, "m.mtl", "newmtl red\nKd 1 0\nKd 1 0 0\nmap_Kd nowhere.png\n");
    let path = write(&dir, "m.obj", &format!("mtllib m.mtl\n{TRI}usemtl red\nf 1 2 3\n"));
    let scene = load(&path).unwrap();
    assert_eq!(scene.warnings.len(), 2, "{:?}", scene.warnings);
    assert_mentions(&scene.warnings[0], &["m.obj", "m.mtl", "line 2"]);
    assert_mentions(&scene.warnings[1], &["nowhere.png", "file not found"]);
    let mat = scene.material(scene.instances()[0].material.unwrap()).unwrap();
    assert_eq!(mat.base_color, [1.0, 0.0, 0.0, 1.0]);
    // A texture that is there is decoded, and v is flipped to the top-row-is-0 convention.
    std::fs::copy(asset("checker.png"), dir.join("nowhere.png")).unwrap();
    let path =
        write(&dir, "uv.obj", &format!("mtllib m.mtl\n{TRI}vt 0 0\nvt 1 0\nvt 0 1\nusemtl red\nf 1/1 2/2 3/3\n"));
    let scene = load(&path).unwrap();
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    let inst = scene.instances()[0];
    let tex = scene.material(inst.material.unwrap()).unwrap().base_color_texture.clone();
    assert_eq!(tex.unwrap().width, 8);
    let uvs = scene.mesh(inst.mesh).unwrap().uvs().unwrap().to_vec();
    assert_eq!(uvs, [glam::Vec2::new(0.0, 1.0), glam::Vec2::new(1.0, 1.0), glam::Vec2::new(0.0, 0.0)]);
}

#[test]
fn obj_errors_name_the_file_and_problem() {
    let dir = tmp_dir("obj-bad");
    let cases = [
        ("index.obj", format!("{TRI}f 1 2 9\n"), "index out of bounds"),
        ("zero.obj", format!("{TRI}f 0 1 2\n"), "out of bounds"),
        ("negative.obj", format!("{TRI}f -1 -2 -9\n"), "out of bounds"),
        ("texneg.obj", format!("{TRI}vt 0 0\nf 1/-5 2/-5 3/-5\n"), "malformed OBJ"),
        ("nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_string(), "not finite"),
        ("inf.obj", "v 1e39 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_string(), "not finite"),
        ("short.obj", "v 1 2\n".to_string(), "line 1: position parse error ('v 1 2')"),
        ("face.obj", format!("{TRI}f 1 x 3\n"), "line 4: face parse error ('f 1 x 3')"),
    ];
    for (name, text, want) in cases {
        let path = write(&dir, name, &text);
        assert_mentions(&err_text(load(&path)), &[name, want]);
    }
    assert_mentions(&err_text(load_obj(&dir.join("absent.obj"))), &["absent.obj", "file not found"]);
}

#[test]
fn obj_groups_become_child_nodes_and_unreferenced_vertices_are_fine() {
    let dir = tmp_dir("groups");
    let path = write(
        &dir,
        "groups.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 9 9 9\nv 1 1 0\no first\nf 1 2 3\ng second\nf 2 5 3\nf 3 2 1\n",
    );
    let scene = load(&path).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let root = scene.roots().next().unwrap();
    let kids: Vec<&str> = scene.node(root).unwrap().children().map(|c| scene.node(c).unwrap().name()).collect();
    assert_eq!(kids, ["first", "second"]);
    assert_eq!(scene.stats().triangles, 3);
    // The unreferenced vertex (9, 9, 9) does not inflate any bounds (world boxes are widened
    // by a bound on their rounding only).
    assert!(scene.world_aabb().max.max_element() <= 1.0 + 1e-5);
}

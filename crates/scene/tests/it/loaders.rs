//! Loader and exporter tests: the authored assets with hand-computed world positions, and
//! small broken files written to a temporary folder, each of which must give an error (or a
//! warning) that names the file and the problem — never a panic.

use std::path::{Path, PathBuf};

use glam::{Affine3A, Quat, Vec3};
use sightline_scene::export::{export_obj, write_obj};
use sightline_scene::gltf_loader::load_gltf;
use sightline_scene::obj_loader::load_obj;
use sightline_scene::*;

use crate::support::{assert_mentions, asset, err_text, TRI};

/// A fresh, empty folder for one test.
fn tmp_dir(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sightline-loaders-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Every drawn triangle's world-space corners, in flattened (triangle ID) order.
fn world_triangles(scene: &Scene) -> Vec<[Vec3; 3]> {
    let mut out = Vec::new();
    for inst in scene.instances() {
        let mesh = scene.mesh(inst.mesh).unwrap();
        for t in 0..mesh.triangle_count() {
            out.push(mesh.triangle_positions(t).map(|p| inst.world_from_local.transform_point3(p)));
        }
    }
    out
}

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

// ---- the authored OBJ ---------------------------------------------------------------------

#[test]
fn cube_obj_loads_with_mtl_color() {
    let scene = load(asset("cube.obj")).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let root = scene.roots()[0];
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
    // Not propagated yet: the exporter must still use the current transforms.
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
    let path = tmp_dir("export-bad").join("no/such/dir/out.obj");
    let e = export_obj(&scene, &path).unwrap_err().to_string();
    assert_mentions(&e, &["out.obj"]);
}

// ---- broken glTF --------------------------------------------------------------------------

fn base64(bytes: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A one-triangle glTF with an embedded buffer: `positions` then u16 `indices`; `edit`
/// changes the JSON before it is written.
fn tiny_gltf(dir: &Path, name: &str, indices: &[u16], edit: impl FnOnce(&mut serde_json::Value)) -> PathBuf {
    let mut buf = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in p {
            buf.extend(c.to_le_bytes());
        }
    }
    for i in indices {
        buf.extend(i.to_le_bytes());
    }
    let mut doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "holder", "mesh": 0}],
        "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
            {"bufferView": 1, "componentType": 5123, "count": indices.len(), "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 2 * indices.len()}
        ],
        "buffers": [{"byteLength": buf.len(), "uri": format!("data:application/octet-stream;base64,{}", base64(&buf))}]
    });
    edit(&mut doc);
    let path = dir.join(name);
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    path
}

#[test]
fn tiny_gltf_is_valid() {
    let dir = tmp_dir("tiny");
    let scene = load(tiny_gltf(&dir, "tiny.gltf", &[0, 1, 2], |_| {})).unwrap();
    assert_eq!(scene.stats().triangles, 1);
    assert!(scene.warnings.is_empty());
}

#[test]
fn truncated_glb_is_an_error() {
    let dir = tmp_dir("trunc");
    let bytes = std::fs::read(asset("nested.glb")).unwrap();
    for cut in [3, 11, 30, bytes.len() / 2, bytes.len() - 1] {
        let path = dir.join(format!("cut{cut}.glb"));
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let e = err_text(load_gltf(&path));
        assert_mentions(&e, &[&format!("cut{cut}.glb"), "truncated"]);
    }
}

#[test]
fn wrong_magic_is_an_error() {
    let dir = tmp_dir("magic");
    let mut bytes = std::fs::read(asset("nested.glb")).unwrap();
    bytes[3] = b'X';
    let path = dir.join("magic.glb");
    std::fs::write(&path, &bytes).unwrap();
    let e = err_text(load(&path));
    assert_mentions(&e, &["magic.glb", "wrong magic", "glTX"]);
}

#[test]
fn invalid_json_is_an_error() {
    let dir = tmp_dir("json");
    let path = dir.join("broken.gltf");
    std::fs::write(&path, "{ \"asset\": { \"version\": \"2.0\" }, \"nodes\": [ {").unwrap();
    let e = err_text(load(&path));
    assert_mentions(&e, &["broken.gltf", "invalid glTF JSON", "line 1"]);
    std::fs::write(&path, "{\"nodes\": []}").unwrap();
    assert_mentions(&err_text(load(&path)), &["broken.gltf", "asset"]);
}

#[test]
fn missing_and_short_bin_are_errors() {
    let dir = tmp_dir("bin");
    let gltf = dir.join("scene.gltf");
    std::fs::copy(asset("nested.gltf"), &gltf).unwrap();
    let e = err_text(load(&gltf));
    assert_mentions(&e, &["scene.gltf", "buffer 0 ('nested.bin')", "file not found"]);
    let bin = std::fs::read(asset("nested.bin")).unwrap();
    std::fs::write(dir.join("nested.bin"), &bin[..100]).unwrap();
    let e = err_text(load(&gltf));
    assert_mentions(&e, &["scene.gltf", "buffer 0", "too short", "100 bytes"]);
}

#[test]
fn accessor_past_its_view_is_an_error() {
    let dir = tmp_dir("accessor");
    let path = tiny_gltf(&dir, "long.gltf", &[0, 1, 2], |d| {
        d["accessors"][0]["count"] = 4.into();
    });
    let e = err_text(load(&path));
    assert_mentions(&e, &["long.gltf", "mesh 0 ('tri') primitive 0", "accessor 0 reads past the end of buffer view 0"]);
    let path = tiny_gltf(&dir, "view.gltf", &[0, 1, 2], |d| {
        d["bufferViews"][1]["byteLength"] = 400.into();
    });
    assert_mentions(&err_text(load(&path)), &["view.gltf", "buffer view 1", "past the end of buffer 0"]);
}

#[test]
fn index_out_of_range_is_an_error() {
    let dir = tmp_dir("index");
    let path = tiny_gltf(&dir, "index.gltf", &[0, 1, 7], |_| {});
    let e = err_text(load(&path));
    assert_mentions(&e, &["index.gltf", "mesh 0 ('tri') primitive 0", "index 7", "out of range"]);
}

#[test]
fn required_unknown_extension_is_an_error_used_one_a_warning() {
    let dir = tmp_dir("ext");
    let path = tiny_gltf(&dir, "required.gltf", &[0, 1, 2], |d| {
        d["extensionsUsed"] = serde_json::json!(["KHR_draco_mesh_compression"]);
        d["extensionsRequired"] = serde_json::json!(["KHR_draco_mesh_compression"]);
    });
    let e = err_text(load(&path));
    assert_mentions(&e, &["required.gltf", "requires extension 'KHR_draco_mesh_compression'"]);
    let path = tiny_gltf(&dir, "used.gltf", &[0, 1, 2], |d| {
        d["extensionsUsed"] = serde_json::json!(["EXT_made_up"]);
    });
    let scene = load(&path).unwrap();
    assert_eq!(scene.stats().triangles, 1);
    assert_eq!(scene.warnings.len(), 1);
    assert_mentions(&scene.warnings[0], &["used.gltf", "EXT_made_up"]);
}

#[test]
fn point_and_line_primitives_are_skipped_with_a_warning() {
    let dir = tmp_dir("points");
    let path = tiny_gltf(&dir, "points.gltf", &[0, 1, 2], |d| {
        d["meshes"][0]["primitives"][0]["mode"] = 0.into();
    });
    let scene = load(&path).unwrap();
    assert_eq!(scene.stats().triangles, 0);
    assert_eq!(scene.node_count(), 1, "the node stays, without a mesh");
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert_mentions(&scene.warnings[0], &["points.gltf", "skipped 1 point/line", "Points"]);
    // A line primitive next to a triangle one: the triangles still load.
    let path = tiny_gltf(&dir, "mixed.gltf", &[0, 1, 2], |d| {
        let p = d["meshes"][0]["primitives"][0].clone();
        let mut lines = p.clone();
        lines["mode"] = 1.into();
        d["meshes"][0]["primitives"] = serde_json::json!([lines, p]);
    });
    let scene = load(&path).unwrap();
    assert_eq!(scene.stats().triangles, 1);
    assert_mentions(&scene.warnings[0], &["mixed.gltf", "Lines"]);
}

#[test]
fn missing_texture_is_a_warning() {
    let dir = tmp_dir("texture");
    std::fs::copy(asset("nested.gltf"), dir.join("nested.gltf")).unwrap();
    std::fs::copy(asset("nested.bin"), dir.join("nested.bin")).unwrap();
    let scene = load(dir.join("nested.gltf")).unwrap();
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert_mentions(&scene.warnings[0], &["nested.gltf", "material 1 ('checker')", "checker.png", "file not found"]);
    let (_, checker) = scene.materials().find(|(_, m)| m.name == "checker").unwrap();
    assert!(checker.base_color_texture.is_none());
    assert_eq!(checker.base_color, [1.0; 4]);
    // A corrupt image is a warning too.
    std::fs::write(dir.join("checker.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let scene = load(dir.join("nested.gltf")).unwrap();
    assert_mentions(&scene.warnings[0], &["checker.png", "decode"]);
}

#[test]
fn node_cycles_and_shared_nodes_are_errors() {
    let dir = tmp_dir("cycle");
    let path = tiny_gltf(&dir, "cycle.gltf", &[0, 1, 2], |d| {
        d["nodes"] = serde_json::json!([{"name": "a", "children": [1]}, {"name": "b", "children": [0]}]);
    });
    assert_mentions(&err_text(load(&path)), &["cycle.gltf", "node 0 ('a') is reached twice"]);
    let path = tiny_gltf(&dir, "self.gltf", &[0, 1, 2], |d| {
        d["nodes"] = serde_json::json!([{"name": "a", "children": [0]}]);
    });
    assert_mentions(&err_text(load(&path)), &["self.gltf", "reached twice"]);
    let path = tiny_gltf(&dir, "shared.gltf", &[0, 1, 2], |d| {
        d["nodes"] = serde_json::json!([{"children": [2]}, {"children": [2]}, {"mesh": 0}]);
        d["scenes"] = serde_json::json!([{"nodes": [0, 1]}]);
    });
    assert_mentions(&err_text(load(&path)), &["shared.gltf", "node 2 is reached twice"]);
    let path = tiny_gltf(&dir, "dangling.gltf", &[0, 1, 2], |d| {
        d["nodes"] = serde_json::json!([{"children": [5]}]);
    });
    assert_mentions(&err_text(load(&path)), &["dangling.gltf", "node 5", "does not exist"]);
    // No scene at all: every parentless node is a root.
    let path = tiny_gltf(&dir, "noscene.gltf", &[0, 1, 2], |d| {
        d.as_object_mut().unwrap().remove("scenes");
        d["nodes"] = serde_json::json!([{"mesh": 0}, {"mesh": 0, "children": [0]}]);
    });
    let scene = load(&path).unwrap();
    assert_eq!(scene.roots().len(), 1);
    assert_eq!(scene.node_count(), 2);
}

#[test]
fn deep_gltf_chain_does_not_overflow_the_stack() {
    let dir = tmp_dir("deep");
    let n = 50_000;
    let path = tiny_gltf(&dir, "deep.gltf", &[0, 1, 2], |d| {
        let nodes: Vec<serde_json::Value> = (0..n)
            .map(|i| {
                if i + 1 < n {
                    serde_json::json!({"children": [i + 1], "translation": [0.0, 0.0, 1.0]})
                } else {
                    serde_json::json!({"mesh": 0})
                }
            })
            .collect();
        d["nodes"] = nodes.into();
    });
    let scene = load(&path).unwrap();
    assert_eq!(scene.node_count(), n);
    let z = world_triangles(&scene)[0][0].z;
    assert_eq!(z, (n - 1) as f32);
}

#[test]
fn non_finite_transform_is_an_error() {
    let dir = tmp_dir("nan");
    let path = tiny_gltf(&dir, "inf.gltf", &[0, 1, 2], |d| {
        d["nodes"][0]["translation"] = serde_json::json!([1e39, 0, 0]);
    });
    assert_mentions(&err_text(load(&path)), &["inf.gltf", "node 0 ('holder')", "NaN or infinite"]);
    let path = tiny_gltf(&dir, "matrix.gltf", &[0, 1, 2], |d| {
        d["nodes"][0]["matrix"] = serde_json::json!([1, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
    });
    assert_mentions(&err_text(load(&path)), &["matrix.gltf", "node 0 ('holder')", "last row"]);
}

#[test]
fn gltf_index_types_strips_fans_and_no_indices() {
    let dir = tmp_dir("modes");
    // No indices: 0..n.
    let path = tiny_gltf(&dir, "plain.gltf", &[0, 1, 2], |d| {
        d["meshes"][0]["primitives"][0].as_object_mut().unwrap().remove("indices");
    });
    assert_eq!(load(&path).unwrap().stats().triangles, 1);
    // u32 indices through the same bytes: 3 u16 = 6 bytes are not a multiple of 4, so use
    // a u8 view of the u16 data instead: [0, 0, 1, 0, 2, 0] read as u8 is 0 0 1 0 2 0.
    let path = tiny_gltf(&dir, "u8.gltf", &[0, 1, 2], |d| {
        d["accessors"][1]["componentType"] = 5121.into();
        d["accessors"][1]["count"] = 6.into();
    });
    let scene = load(&path).unwrap();
    assert_eq!(scene.stats().triangles, 2);
    // Float indices are refused.
    let path = tiny_gltf(&dir, "float.gltf", &[0, 1, 2, 0, 0, 0], |d| {
        d["accessors"][1]["componentType"] = 5126.into();
        d["accessors"][1]["count"] = 3.into();
    });
    assert_mentions(&err_text(load(&path)), &["float.gltf", "indices must be unsigned"]);
    // A strip of 5 indices gives 3 triangles, alternating so that all keep their winding.
    let path = tiny_gltf(&dir, "strip.gltf", &[0, 1, 2, 1, 0], |d| {
        d["meshes"][0]["primitives"][0]["mode"] = 5.into();
    });
    let scene = load(&path).unwrap();
    let mesh = scene.meshes().next().unwrap().1;
    assert_eq!(mesh.indices(), [0, 1, 2, 1, 1, 2, 2, 1, 0]);
    let path = tiny_gltf(&dir, "fan.gltf", &[2, 0, 1, 0], |d| {
        d["meshes"][0]["primitives"][0]["mode"] = 6.into();
    });
    let scene = load(&path).unwrap();
    let mesh = scene.meshes().next().unwrap().1;
    assert_eq!(mesh.indices(), [2, 0, 1, 2, 1, 0]);
}

#[test]
fn other_gltf_problems_name_the_file() {
    let dir = tmp_dir("misc");
    type Edit = Box<dyn FnOnce(&mut serde_json::Value)>;
    let cases: Vec<(&str, Edit, &str)> = vec![
        (
            "nopos.gltf",
            Box::new(|d| d["meshes"][0]["primitives"][0]["attributes"] = serde_json::json!({"NORMAL": 0})),
            "no POSITION",
        ),
        (
            "badacc.gltf",
            Box::new(|d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 9.into()),
            "accessor 9 does not exist",
        ),
        ("vec2.gltf", Box::new(|d| d["accessors"][0]["type"] = "VEC2".into()), "expected one of [Vec3]"),
        ("nomesh.gltf", Box::new(|d| d["nodes"][0]["mesh"] = 4.into()), "mesh 4, which does not exist"),
        (
            "scheme.gltf",
            Box::new(|d| d["buffers"][0]["uri"] = "https://example.invalid/x.bin".into()),
            "unsupported URI scheme",
        ),
        (
            "b64.gltf",
            Box::new(|d| d["buffers"][0]["uri"] = "data:application/octet-stream;base64,@@@@".into()),
            "invalid base64",
        ),
        ("version.gltf", Box::new(|d| d["asset"]["version"] = "1.0".into()), "unsupported glTF version"),
        ("scene.gltf", Box::new(|d| d["scene"] = 3.into()), "default scene 3 does not exist"),
        ("stride.gltf", Box::new(|d| d["bufferViews"][0]["byteStride"] = 4.into()), "byteStride 4"),
    ];
    for (name, edit, want) in cases {
        let path = tiny_gltf(&dir, name, &[0, 1, 2], edit);
        assert_mentions(&err_text(load(&path)), &[name, want]);
    }
}

#[test]
fn unreadable_gltf_names_the_file() {
    let e = err_text(load(tmp_dir("gone").join("gone.glb")));
    assert_mentions(&e, &["gone.glb", "file not found"]);
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
        ("short.obj", "v 1 2\n".to_string(), "position parse error"),
        ("face.obj", format!("{TRI}f 1 x 3\n"), "face parse error"),
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
    let root = scene.roots()[0];
    let kids: Vec<&str> = scene.node(root).unwrap().children().iter().map(|&c| scene.node(c).unwrap().name()).collect();
    assert_eq!(kids, ["first", "second"]);
    assert_eq!(scene.stats().triangles, 3);
    // The unreferenced vertex (9, 9, 9) does not inflate any bounds.
    assert!(scene.world_aabb().max.max_element() <= 1.0);
}

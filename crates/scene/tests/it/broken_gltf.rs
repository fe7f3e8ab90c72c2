//! Broken glTF files, each written small to a temporary folder: every one must give an
//! error (or a warning) that names the file and the problem — never a panic.

use sightline_scene::gltf_loader::load_gltf;
use sightline_scene::*;

use crate::support::{assert_mentions, asset, err_text, tiny_gltf, tmp_dir, world_triangles};

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
fn node_cycles_are_errors() {
    let dir = tmp_dir("cycle");
    let path = tiny_gltf(&dir, "cycle.gltf", &[0, 1, 2], |d| {
        d["nodes"] = serde_json::json!([{"name": "a", "children": [1]}, {"name": "b", "children": [0]}]);
    });
    assert_mentions(&err_text(load(&path)), &["cycle.gltf", "node 0 ('a') is its own ancestor", "cycle"]);
    let path = tiny_gltf(&dir, "self.gltf", &[0, 1, 2], |d| {
        d["nodes"] = serde_json::json!([{"name": "a", "children": [0]}]);
    });
    assert_mentions(&err_text(load(&path)), &["self.gltf", "its own ancestor"]);
    // A cycle below a shared node is found on every path.
    let path = tiny_gltf(&dir, "deep_cycle.gltf", &[0, 1, 2], |d| {
        d["nodes"] = serde_json::json!([{"children": [2]}, {"children": [2]}, {"children": [3]}, {"children": [2]}]);
        d["scenes"] = serde_json::json!([{"nodes": [0, 1]}]);
    });
    assert_mentions(&err_text(load(&path)), &["deep_cycle.gltf", "node 2 is its own ancestor"]);
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
    assert_eq!(scene.roots().count(), 1);
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
    let dir = tmp_dir("gone");
    let e = err_text(load(dir.join("gone.glb")));
    assert_mentions(&e, &["gone.glb", "file not found"]);
}

/// Accessors without a buffer view are zeros: a few bytes of JSON. Many of them must not add
/// up to gigabytes (eight of 2^24 − 1 elements once took 2.2 GB and 4 s for a 762-byte file).
#[test]
fn zero_filled_accessors_are_capped_per_load() {
    let dir = tmp_dir("unbacked");
    let unbacked = |count: u64, prims: usize| {
        move |d: &mut serde_json::Value| {
            d["accessors"] = (0..prims)
                .map(|_| serde_json::json!({"componentType": 5126, "count": count, "type": "VEC3"}))
                .collect();
            d["meshes"][0]["primitives"] =
                (0..prims).map(|i| serde_json::json!({"attributes": {"POSITION": i}})).collect();
        }
    };
    // One small one loads: zeros, one degenerate triangle.
    let s = load(tiny_gltf(&dir, "small.gltf", &[], unbacked(3, 1))).unwrap();
    assert_eq!(s.stats().degenerate_triangles, 1);
    // Two that each fit the cap but together do not.
    let path = tiny_gltf(&dir, "many.gltf", &[], unbacked(9_000_000, 2));
    let roomy = LoadOptions::default().max_decoded_bytes(1 << 40);
    assert_mentions(&err_text(load_with(&path, &roomy)), &["many.gltf", "accessor 1", "no buffer view", "in all"]);
    // The default cap on decoded data stops the first already: 108 MB from a tiny file.
    assert_mentions(&err_text(load(&path)), &["many.gltf", "accessor 0 (9000000 elements)", "the default limit"]);
}

//! Shared subgraphs: a subtree or a whole scene placed many times without copying meshes
//! (instantiate, prefabs, load_into), and glTF files whose node graph is a DAG.

use glam::{Affine3A, Quat, Vec3};
use sightline_scene::*;

use crate::support::{assert_mentions, asset, err_text, tiny_gltf, tmp_dir, world_triangles};

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-4
}

/// A robot: "body" (cube, red) with an "arm" group holding a "hand" (cube), a camera on the
/// hand; and a separate "ground" root.
fn robot() -> (Scene, NodeId, NodeId) {
    let mut s = Scene::new();
    let cube = s.add_mesh(shapes::cube("cube").unwrap());
    let red = s.add_material(Material::color("red", [1.0, 0.0, 0.0]));
    let body = s
        .add_node(None, NodeDesc::new("body").mesh(cube).material(red).transform(Transform::from_translation(Vec3::Y)))
        .unwrap();
    let arm = s.add_node(Some(body), NodeDesc::new("arm").transform(Transform::from_translation(Vec3::X))).unwrap();
    let hand = s.add_node(Some(arm), NodeDesc::new("hand").mesh(cube)).unwrap();
    s.add_node(None, NodeDesc::new("ground").mesh(cube)).unwrap();
    let projection = Projection::perspective(Angle::degrees(40.0), 1.0, 0.1, 10.0).unwrap();
    s.cameras.push(SceneCamera { name: "hand cam".into(), node: hand, projection });
    s.update_transforms();
    (s, body, hand)
}

fn origin(s: &Scene, n: NodeId) -> Vec3 {
    s.node(n).unwrap().world_matrix().translation.into()
}

#[test]
fn instantiate_copies_nodes_and_shares_meshes() {
    let (mut s, body, _) = robot();
    let (meshes, materials, nodes) = (s.meshes().count(), s.materials().count(), s.node_count());
    let at = Transform::from_translation(Vec3::new(0.0, 0.0, 5.0));
    let copy = s.instantiate(body, None, at).unwrap();
    assert_eq!((s.meshes().count(), s.materials().count()), (meshes, materials), "nothing heavy is copied");
    assert_eq!(s.node_count(), nodes + 3);
    assert!(s.needs_update());
    s.update_transforms();
    assert_eq!(s.changes().added.len(), 2, "body and hand copies");
    let n = s.node(copy).unwrap();
    assert_eq!(
        (n.name(), n.mesh(), n.material()),
        ("body", s.node(body).unwrap().mesh(), s.node(body).unwrap().material())
    );
    assert!(close(origin(&s, copy), Vec3::new(0.0, 0.0, 5.0)), "the copy takes the given transform");
    let hand_copy = s.node(s.node(copy).unwrap().children().next().unwrap()).unwrap().children().next().unwrap();
    assert!(close(origin(&s, hand_copy), Vec3::new(1.0, 0.0, 5.0)));
    assert_eq!(s.instance(hand_copy).unwrap().material, s.node(body).unwrap().material(), "inherited in the copy");
    // The camera on the hand came along, on the copy's hand.
    assert_eq!(s.cameras.len(), 2);
    assert_eq!(s.cameras[1].node, hand_copy);
    // The copies are independent: moving one leaves the other.
    s.set_local_transform(copy, Transform::IDENTITY).unwrap();
    s.update_transforms();
    assert!(close(origin(&s, body), Vec3::Y));
}

#[test]
fn instantiate_under_its_own_subtree_copies_the_subtree_as_it_was() {
    let (mut s, body, hand) = robot();
    let before = s.node_count();
    let copy = s.instantiate(body, Some(hand), Transform::from_translation(Vec3::Z)).unwrap();
    assert_eq!(s.node_count(), before + 3);
    assert_eq!(s.node(copy).unwrap().parent(), Some(hand));
    s.update_transforms();
    assert!(close(origin(&s, copy), Vec3::new(1.0, 1.0, 1.0)));
}

#[test]
fn bad_instantiations_change_nothing() {
    let (mut s, body, hand) = robot();
    let before = (s.node_count(), s.revision(), s.cameras.len());
    let gone = s.add_node(None, NodeDesc::new("gone")).unwrap();
    s.remove_node(gone).unwrap();
    s.update_transforms();
    let before = (before.0, before.1 + 1, before.2);
    assert!(matches!(s.instantiate(gone, None, Transform::IDENTITY), Err(Error::StaleNode(_))));
    assert!(matches!(s.instantiate(body, Some(gone), Transform::IDENTITY), Err(Error::StaleNode(_))));
    let e = s.instantiate(hand, None, Transform::from_translation(Vec3::NAN)).unwrap_err();
    assert_mentions(&e.to_string(), &["copy of node 'hand'", "NaN"]);
    assert_eq!((s.node_count(), s.revision(), s.cameras.len()), before);
    assert!(!s.needs_update());
}

#[test]
fn a_prefab_is_added_once_and_placed_many_times() {
    let (model, _, _) = robot();
    let mut s = Scene::new();
    let crowd =
        s.add_node(None, NodeDesc::new("crowd").transform(Transform::from_translation(Vec3::X * 100.0))).unwrap();
    let prefab = s.add_prefab(&model).with_name("robot");
    assert_eq!(prefab.node_count(), 4);
    assert_eq!(s.meshes().count(), 1, "one cube, used by three nodes");
    assert_eq!(s.materials().count(), 1);
    let placed: Vec<NodeId> = (0..10)
        .map(|i| {
            let at =
                Transform::from_translation(Vec3::Z * i as f32).with_rotation(Quat::from_rotation_y(0.1 * i as f32));
            s.instantiate_prefab(&prefab, Some(crowd), at).unwrap()
        })
        .collect();
    assert_eq!(s.meshes().count(), 1, "placing copies no mesh");
    assert_eq!(s.node_count(), 1 + 10 * 5);
    assert_eq!(s.cameras.len(), 10);
    s.update_transforms();
    assert_eq!(s.instances().len(), 30);
    // Each placement's world triangles are the model's under the placement's transform.
    let model_tris = world_triangles(&model);
    let tris = world_triangles(&s);
    for (k, &p) in placed.iter().enumerate() {
        let m = s.node(p).unwrap().world_matrix();
        assert_eq!(s.node(p).unwrap().name(), "robot");
        for (t, want) in tris[k * model_tris.len()..].iter().zip(&model_tris) {
            for c in 0..3 {
                assert!(close(t[c], m.transform_point3(want[c])), "placement {k}");
            }
        }
    }
    // Moving the parent moves every placement's drawn nodes.
    s.set_local_transform(crowd, Transform::IDENTITY).unwrap();
    s.update_transforms();
    assert_eq!(s.changes().moved.len(), 30);
    // A prefab belongs to its scene: a clone is another scene.
    let mut other = s.clone();
    let e = other.instantiate_prefab(&prefab, None, Transform::IDENTITY).unwrap_err();
    assert!(matches!(e, Error::ForeignPrefab { .. }));
    assert_mentions(&e.to_string(), &["prefab 'robot'", "another scene", "add_prefab"]);
}

#[test]
fn instantiate_from_places_a_whole_scene_once() {
    let (mut model, _, _) = robot();
    model.warnings.push("robot.gltf: a warning".into());
    let mut s = Scene::new();
    let root = s.instantiate_from(&model, None, Transform::from_scale(Vec3::splat(2.0))).unwrap();
    assert_eq!(s.roots().collect::<Vec<_>>(), [root]);
    assert_eq!(s.node(root).unwrap().children().count(), 2, "body and ground");
    s.update_transforms();
    let want: Vec<[Vec3; 3]> = world_triangles(&model)
        .iter()
        .map(|t| t.map(|p| Affine3A::from_scale(Vec3::splat(2.0)).transform_point3(p)))
        .collect();
    let got = world_triangles(&s);
    assert_eq!(got.len(), want.len());
    assert!(got.iter().zip(&want).all(|(a, b)| (0..3).all(|c| close(a[c], b[c]))));
    let (_, red) = s.materials().next().unwrap();
    assert_eq!(red.name, "red");
    assert_eq!(s.warnings, model.warnings, "the model's warnings came along");
}

#[test]
fn load_into_places_a_file_under_a_parent() {
    let mut s = Scene::new();
    let parent =
        s.add_node(None, NodeDesc::new("shelf").transform(Transform::from_translation(Vec3::Y * 3.0))).unwrap();
    let opts = LoadOptions::default();
    let node = load_into(&mut s, asset("nested.gltf"), Some(parent), &opts).unwrap();
    assert_eq!(s.node(node).unwrap().name(), "nested.gltf");
    assert_eq!(s.node(node).unwrap().parent(), Some(parent));
    assert_eq!(s.cameras.len(), 1, "the file's camera came along");
    s.update_transforms();
    let file = load(asset("nested.gltf")).unwrap();
    let want: Vec<[Vec3; 3]> = world_triangles(&file).iter().map(|t| t.map(|p| p + Vec3::Y * 3.0)).collect();
    let got = world_triangles(&s);
    assert!(!got.is_empty() && got.len() == want.len());
    assert!(got.iter().zip(&want).all(|(a, b)| (0..3).all(|c| close(a[c], b[c]))));
    // A prefab of the file places it again without adding meshes.
    let meshes = s.meshes().count();
    let prefab = load_prefab(&mut s, asset("nested.gltf"), &opts).unwrap();
    let meshes_after_prefab = s.meshes().count();
    assert_eq!(meshes_after_prefab, 2 * meshes, "one load adds the file's meshes once");
    for i in 0..3 {
        s.instantiate_prefab(&prefab, None, Transform::from_translation(Vec3::X * i as f32)).unwrap();
    }
    assert_eq!(s.meshes().count(), meshes_after_prefab);
    // A stale parent is refused before the file is read; a missing file names itself.
    s.remove_node(parent).unwrap();
    let count = s.node_count();
    assert!(matches!(load_into(&mut s, asset("nested.gltf"), Some(parent), &opts), Err(Error::StaleNode(_))));
    let e = load_into(&mut s, asset("missing.gltf"), None, &opts).unwrap_err();
    assert_mentions(&e.to_string(), &["missing.gltf"]);
    assert_eq!(s.node_count(), count);
}

#[test]
fn a_gltf_node_with_two_parents_loads_as_two_instances_of_one_mesh() {
    let dir = tmp_dir("shared-node");
    let path = tiny_gltf(&dir, "shared_node.gltf", &[0, 1, 2], |d| {
        d["nodes"] = serde_json::json!([
            {"name": "left", "children": [2]},
            {"name": "right", "translation": [5, 0, 0], "children": [2]},
            {"name": "wheel", "mesh": 0, "translation": [0, 1, 0], "camera": 0}
        ]);
        d["scenes"] = serde_json::json!([{"nodes": [0, 1]}]);
        d["cameras"] =
            serde_json::json!([{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 50}}]);
    });
    let s = load(&path).unwrap();
    assert_eq!(s.node_count(), 4);
    assert_eq!(s.meshes().count(), 1, "one mesh, shared");
    let inst = s.instances();
    assert_eq!(inst.len(), 2);
    assert_eq!(inst[0].mesh, inst[1].mesh);
    assert_ne!(inst[0].node, inst[1].node);
    assert!(close(inst[0].world_from_local.translation.into(), Vec3::Y));
    assert!(close(inst[1].world_from_local.translation.into(), Vec3::new(5.0, 1.0, 0.0)));
    assert!(inst.iter().all(|i| s.node(i.node).unwrap().name() == "wheel"));
    assert_eq!(s.cameras.len(), 2, "one camera per copy of its node");
    assert_ne!(s.cameras[0].node, s.cameras[1].node);
}

#[test]
fn an_exponential_gltf_dag_stops_at_the_node_limit() {
    let dir = tmp_dir("dag-bomb");
    // Node k has node k+1 twice as its child: 2^40 paths reach the last node.
    let layers = 40;
    let path = tiny_gltf(&dir, "bomb.gltf", &[0, 1, 2], |d| {
        let mut nodes: Vec<serde_json::Value> =
            (0..layers).map(|k| serde_json::json!({"children": [k + 1, k + 1]})).collect();
        nodes.push(serde_json::json!({"mesh": 0}));
        d["nodes"] = serde_json::Value::Array(nodes);
    });
    let opts = LoadOptions::default().max_nodes(10_000);
    let e = err_text(load_with(&path, &opts));
    assert_mentions(&e, &["bomb.gltf", "more than 10000 nodes", "LoadOptions::max_nodes"]);
    // Ten layers (2^11 - 1 nodes) fit in a limit of 4096.
    let path = tiny_gltf(&dir, "small.gltf", &[0, 1, 2], |d| {
        let mut nodes: Vec<serde_json::Value> =
            (0..10).map(|k| serde_json::json!({"children": [k + 1, k + 1]})).collect();
        nodes.push(serde_json::json!({"mesh": 0}));
        d["nodes"] = serde_json::Value::Array(nodes);
    });
    let s = load_with(&path, &LoadOptions::default().max_nodes(4096)).unwrap();
    assert_eq!(s.node_count(), 2047);
    assert_eq!(s.instances().len(), 1024);
    assert_eq!(s.meshes().count(), 1);
    assert!(load_with(&path, &LoadOptions::default().max_nodes(2000)).is_err());
}

/// A node listing one child a million times is refused before the million entries are
/// stacked, naming the node; its long name is not copied once per entry.
#[test]
fn a_node_listing_a_child_a_million_times_stops_at_the_node_limit() {
    let dir = tmp_dir("wide-bomb");
    let name = "n".repeat(100_000);
    let path = tiny_gltf(&dir, "wide.gltf", &[0, 1, 2], |d| {
        let children = vec![1; 1_000_000];
        d["nodes"] = serde_json::json!([{"name": name, "children": children}, {"mesh": 0}]);
    });
    let opts = LoadOptions::default().max_nodes(10_000);
    let e = err_text(load_with(&path, &opts));
    assert_mentions(&e, &["wide.gltf", "more than 10000 nodes", "1000000 children", "LoadOptions::max_nodes"]);
    assert!(e.len() < 1000, "the long name is cut in the message: {} bytes", e.len());
}

/// A glTF node shared by two parents and animated: the channel drives both copies.
/// assets/animated.gltf's "hand" (scale STEP 1 → 2 at t = 1, translation CUBICSPLINE) is made
/// a child of "base" as well as of "arm".
#[test]
fn an_animated_node_shared_by_two_parents_moves_in_both_copies() {
    let text = std::fs::read_to_string(asset("animated.gltf")).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    doc["nodes"][0]["children"] = serde_json::json!([1, 2]);
    let dir = tmp_dir("shared-animated");
    let path = dir.join("shared_animated.gltf");
    std::fs::write(&path, doc.to_string()).unwrap();
    let mut s = load(&path).unwrap();
    let hands: Vec<NodeId> = s.depth_first().filter(|&id| s.node(id).unwrap().name() == "hand").collect();
    assert_eq!(hands.len(), 2, "one copy per parent");
    // Base, arm, then each channel of the hand once per copy: 1 + 1 + 2 + 2 poses set.
    assert_eq!(s.animate(1.5).unwrap(), 6);
    for &h in &hands {
        let t = s.local_transform(h).unwrap();
        assert!(close(t.scale, Vec3::splat(2.0)), "{:?}", t.scale);
    }
    let (a, b) = (s.local_transform(hands[0]).unwrap(), s.local_transform(hands[1]).unwrap());
    assert_eq!(a, b, "both copies take the same pose");
    assert!(a.translation.y > 1.0, "the translation channel moved the hand: {}", a.translation);
}

/// A million meshes naming one accessor would decode it a million times: the load stops at
/// the decoded-data limit, naming the accessor and the option; at the limit it loads.
#[test]
fn meshes_sharing_one_accessor_stop_at_the_decoded_data_limit() {
    let dir = tmp_dir("accessor-bomb");
    let bomb = |name: &str, meshes: usize, indices: &[u16]| {
        tiny_gltf(&dir, name, indices, |d| {
            let prim = d["meshes"][0]["primitives"][0].clone();
            d["meshes"] = serde_json::Value::Array(vec![serde_json::json!({"primitives": [prim]}); meshes]);
            let nodes: Vec<_> = (0..meshes).map(|m| serde_json::json!({"mesh": m})).collect();
            d["nodes"] = serde_json::Value::Array(nodes);
            d["scenes"] = serde_json::json!([{"nodes": (0..meshes).collect::<Vec<_>>()}]);
        })
    };
    // 1,000 meshes, each decoding the shared accessors: 9 position components and 3,000
    // indices at 4 bytes each; the nodes' names ("node 0" to "node 999") take 7,890 bytes.
    let indices: Vec<u16> = (0..3000).map(|k| (k % 3) as u16).collect();
    let path = bomb("bomb.gltf", 1000, &indices);
    let exact = 1000 * (9 + 3000) * 4 + 7890;
    let e = err_text(load_with(&path, &LoadOptions::default().max_decoded_bytes(exact - 1)));
    let limit = format!("over its limit of {} bytes", exact - 1);
    assert_mentions(&e, &["bomb.gltf", "mesh 999", "accessor", &limit, "LoadOptions::max_decoded_bytes"]);
    let s = load_with(&path, &LoadOptions::default().max_decoded_bytes(exact)).unwrap();
    assert_eq!(s.meshes().count(), 1000);
    // 5,000 meshes naming one index accessor of 30,000 elements: a file of about 0.4 MB
    // asking for 600 MB is refused by the default limit.
    let big: Vec<u16> = (0..30_000).map(|k| (k % 3) as u16).collect();
    let e = err_text(load(bomb("big.gltf", 5000, &big)));
    assert_mentions(&e, &["big.gltf", "decoding index accessor 1 (30000 elements)", "the default limit"]);
}

/// A node reached along 2^16 paths is loaded once per path; a long name, a camera's long
/// name and an animation curve on it would be copied each time: each is charged, and the
/// load stops at the limit.
#[test]
fn copies_of_a_shared_node_are_charged_for_its_name_camera_and_curves() {
    let dir = tmp_dir("copy-bomb");
    let layers = 16;
    let long = "n".repeat(10_000);
    #[derive(Clone, Copy, PartialEq)]
    enum Leaf {
        Plain,
        LongName,
        Camera,
        Animated,
    }
    let file = |name: &str, leaf: Leaf| {
        tiny_gltf(&dir, name, &[0, 1, 2], |d| {
            let mut nodes: Vec<serde_json::Value> =
                (0..layers).map(|k| serde_json::json!({"children": [k + 1, k + 1]})).collect();
            let leaf_name = if leaf == Leaf::LongName { long.clone() } else { "leaf".into() };
            nodes.push(serde_json::json!({"mesh": 0, "name": leaf_name}));
            if leaf == Leaf::Camera {
                nodes[layers]["camera"] = serde_json::json!(0);
                d["cameras"] = serde_json::json!([{"name": long, "type": "perspective",
                    "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 50}}]);
            }
            d["nodes"] = serde_json::Value::Array(nodes);
            if leaf == Leaf::Animated {
                // 1,000 keys of translation: 16 KB a copy.
                let keys = 1000usize;
                let mut buf = Vec::new();
                for k in 0..keys {
                    buf.extend((k as f32).to_le_bytes());
                }
                for k in 0..keys {
                    for c in [k as f32, 0.0, 0.0] {
                        buf.extend(c.to_le_bytes());
                    }
                }
                let uri = format!("data:application/octet-stream;base64,{}", crate::support::base64(&buf));
                d["buffers"].as_array_mut().unwrap().push(serde_json::json!({"byteLength": buf.len(), "uri": uri}));
                let views = d["bufferViews"].as_array_mut().unwrap();
                views.push(serde_json::json!({"buffer": 1, "byteOffset": 0, "byteLength": keys * 4}));
                views.push(serde_json::json!({"buffer": 1, "byteOffset": keys * 4, "byteLength": keys * 12}));
                let acc = d["accessors"].as_array_mut().unwrap();
                acc.push(serde_json::json!({"bufferView": 2, "componentType": 5126, "count": keys, "type": "SCALAR"}));
                acc.push(serde_json::json!({"bufferView": 3, "componentType": 5126, "count": keys, "type": "VEC3"}));
                d["animations"] = serde_json::json!([{
                    "channels": [{"sampler": 0, "target": {"node": layers, "path": "translation"}}],
                    "samplers": [{"input": 2, "output": 3}]
                }]);
            }
        })
    };
    let opts = LoadOptions::default().max_nodes(1 << 20).max_decoded_bytes(100 << 20);
    // 65,536 copies of a 10,000-byte name: 655 MB.
    let e = err_text(load_with(file("names.gltf", Leaf::LongName), &opts));
    assert_mentions(&e, &["names.gltf", "the name of node 16", "LoadOptions::max_decoded_bytes"]);
    assert!(e.len() < 1000, "the long name is cut in the message: {} bytes", e.len());
    // 65,536 cameras named with 10,000 bytes.
    let e = err_text(load_with(file("cameras.gltf", Leaf::Camera), &opts));
    assert_mentions(&e, &["cameras.gltf", "the name of camera 0", "max_decoded_bytes"]);
    // 65,536 copies of a 16,000-byte curve: 1 GB.
    let e = err_text(load_with(file("curves.gltf", Leaf::Animated), &opts));
    assert_mentions(&e, &["curves.gltf", "animation 0 channel 0", "copying its curve", "max_decoded_bytes"]);
    // The same graph with a short name, no camera and no animation loads under that limit.
    let s = load_with(file("plain.gltf", Leaf::Plain), &opts).unwrap();
    assert_eq!(s.instances().len(), 1 << layers);
}

/// A mesh's name is kept with each of its primitives: a long name on a mesh of many
/// primitives is charged per primitive.
#[test]
fn a_mesh_name_kept_per_primitive_is_charged() {
    let dir = tmp_dir("prim-names");
    let path = tiny_gltf(&dir, "prims.gltf", &[0, 1, 2], |d| {
        let prim = d["meshes"][0]["primitives"][0].clone();
        d["meshes"][0]["name"] = serde_json::json!("m".repeat(100_000));
        d["meshes"][0]["primitives"] = serde_json::Value::Array(vec![prim; 2000]);
    });
    // 2,000 copies of 100,000 bytes: 200 MB.
    let e = err_text(load_with(&path, &LoadOptions::default().max_decoded_bytes(100 << 20)));
    assert_mentions(&e, &["prims.gltf", "primitive", "the mesh's name", "max_decoded_bytes"]);
    assert!(e.len() < 1000, "the long name is cut in the message: {} bytes", e.len());
    let s = load_with(&path, &LoadOptions::default().max_decoded_bytes(300 << 20)).unwrap();
    assert_eq!(s.instances().len(), 2000);
}

/// Images naming one small file that decodes to 16 MB each: their texels are charged
/// before each is decoded, and those past the cap are skipped with a warning (a texture is
/// never needed to draw).
#[test]
fn images_sharing_one_file_are_charged_for_their_texels() {
    let dir = tmp_dir("image-bomb");
    let with_images = |name: &str, png: &[u8], n: usize| {
        tiny_gltf(&dir, name, &[0, 1, 2], |d| {
            let uri = format!("data:image/png;base64,{}", crate::support::base64(png));
            d["buffers"].as_array_mut().unwrap().push(serde_json::json!({"byteLength": png.len(), "uri": uri}));
            d["bufferViews"].as_array_mut().unwrap().push(serde_json::json!({"buffer": 1, "byteLength": png.len()}));
            d["images"] = (0..n).map(|_| serde_json::json!({"bufferView": 2, "mimeType": "image/png"})).collect();
            d["textures"] = (0..n).map(|i| serde_json::json!({"source": i})).collect();
            d["materials"] = (0..n)
                .map(|i| serde_json::json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": i}}}))
                .collect();
            let prim = d["meshes"][0]["primitives"][0].clone();
            d["meshes"][0]["primitives"] = (0..n)
                .map(|i| {
                    let mut p = prim.clone();
                    p["material"] = serde_json::json!(i);
                    p
                })
                .collect();
        })
    };
    let textured = |s: &Scene| s.materials().filter(|(_, m)| m.base_color_texture.is_some()).count();
    let png = crate::support::blank_png(2048);
    let path = with_images("images.gltf", &png, 1000);
    assert!(std::fs::metadata(&path).unwrap().len() < 1 << 20, "a small file");
    // The default cap (64 MiB and a little) holds three or four: the rest are skipped.
    let s = load(&path).unwrap();
    let kept = textured(&s);
    assert!((1..10).contains(&kept), "{kept} textures kept");
    let refused = s.warnings.iter().filter(|w| w.contains("decoding its 2048 × 2048 texels")).count();
    assert_eq!(refused, 1000 - kept, "{:?}", &s.warnings[..3]);
    assert_mentions(&s.warnings[0], &["images.gltf", "image", "the default limit", "using the base color factor"]);
    // Ten of them take 160 MiB of texels (4 bytes each): with the mesh's data they fit in
    // 170 MiB; in 160 MiB the last is skipped.
    let path = with_images("few.gltf", &png, 10);
    assert_eq!(textured(&load_with(&path, &LoadOptions::default().max_decoded_bytes(170 << 20)).unwrap()), 10);
    let s = load_with(&path, &LoadOptions::default().max_decoded_bytes(160 << 20)).unwrap();
    assert_eq!(textured(&s), 9);
    assert_mentions(&s.warnings.join("\n"), &["image 9", "decoding its 2048 × 2048 texels", "max_decoded_bytes"]);
    // The charge comes before decoding: a header promising 16384 × 16384 texels over no
    // pixel data is refused for its size, not found undecodable.
    let path = with_images("header.gltf", &crate::support::png_header_only(16384), 1);
    let s = load_with(&path, &LoadOptions::default().max_decoded_bytes(100 << 20)).unwrap();
    assert_mentions(&s.warnings.join("\n"), &["decoding its 16384 × 16384 texels", "max_decoded_bytes"]);
    let s = load_with(&path, &LoadOptions::default().max_decoded_bytes(2 << 30)).unwrap();
    assert_mentions(&s.warnings.join("\n"), &["image 0", "cannot decode"]);
}

/// A node reached along 1,024 paths with an unusable camera (or one that does not exist)
/// is reported once, not once per copy; a usable one is placed on every copy.
#[test]
fn a_shared_node_reports_its_unusable_camera_once() {
    let dir = tmp_dir("camera-copies");
    let file = |name: &str, camera: usize| {
        tiny_gltf(&dir, name, &[0, 1, 2], |d| {
            let mut nodes: Vec<serde_json::Value> =
                (0..10).map(|k| serde_json::json!({"children": [k + 1, k + 1]})).collect();
            nodes.push(serde_json::json!({"mesh": 0, "camera": camera}));
            d["nodes"] = serde_json::Value::Array(nodes);
            d["cameras"] = serde_json::json!([
                {"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 50}},
                {"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.0, "zfar": 50}}
            ]);
        })
    };
    let s = load(file("good.gltf", 0)).unwrap();
    assert_eq!((s.cameras.len(), s.warnings.len()), (1024, 0), "{:?}", s.warnings);
    for (name, camera, why) in [("bad.gltf", 1, "camera 1 on node 10"), ("missing.gltf", 7, "refers to camera 7")] {
        let s = load(file(name, camera)).unwrap();
        assert_eq!(s.cameras.len(), 0);
        assert_eq!(s.warnings.len(), 1, "{:?}", &s.warnings[..s.warnings.len().min(3)]);
        assert_mentions(&s.warnings[0], &[name, why, "ignored"]);
    }
}

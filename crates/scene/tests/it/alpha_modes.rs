//! Alpha modes of materials: glTF `alphaMode` / `alphaCutoff` (defaults, bad values as
//! warnings), OBJ dissolve, and the transparent asset.

use sightline_scene::*;

use crate::support::{assert_mentions, asset, err_text, tiny_gltf, tmp_dir};

/// The material of the tiny glTF's one triangle after `material` (JSON) is attached to it.
fn tiny_with_material(test: &str, material: serde_json::Value) -> Result<Scene> {
    let dir = tmp_dir(test);
    let path = tiny_gltf(&dir, "m.gltf", &[0, 1, 2], |doc| {
        doc["materials"] = serde_json::json!([material]);
        doc["meshes"][0]["primitives"][0]["material"] = serde_json::json!(0);
    });
    load(&path)
}

fn only_material(scene: &Scene) -> &Material {
    let inst = scene.instances();
    scene.material(inst[0].material.expect("the triangle has a material")).unwrap()
}

fn material_named<'s>(scene: &'s Scene, name: &str) -> &'s Material {
    scene.materials().map(|(_, m)| m).find(|m| m.name == name).unwrap_or_else(|| panic!("no material '{name}'"))
}

#[test]
fn gltf_alpha_modes_and_defaults() {
    let cases = [
        (serde_json::json!({"name": "plain"}), AlphaMode::Opaque),
        (serde_json::json!({"alphaMode": "OPAQUE", "alphaCutoff": 0.7}), AlphaMode::Opaque),
        (serde_json::json!({"alphaMode": "MASK"}), AlphaMode::Mask { cutoff: 0.5 }),
        (serde_json::json!({"alphaMode": "MASK", "alphaCutoff": 0.25}), AlphaMode::Mask { cutoff: 0.25 }),
        (serde_json::json!({"alphaMode": "MASK", "alphaCutoff": 0}), AlphaMode::Mask { cutoff: 0.0 }),
        // Valid by the specification (only a minimum is given): nothing passes.
        (serde_json::json!({"alphaMode": "MASK", "alphaCutoff": 1.5}), AlphaMode::Mask { cutoff: 1.5 }),
        (serde_json::json!({"alphaMode": "BLEND", "alphaCutoff": 0.9}), AlphaMode::Blend),
    ];
    for (k, (json, want)) in cases.into_iter().enumerate() {
        let scene = tiny_with_material(&format!("alpha_ok{k}"), json.clone()).unwrap();
        assert!(scene.warnings.is_empty(), "{json}: {:?}", scene.warnings);
        assert_eq!(only_material(&scene).alpha_mode, want, "{json}");
    }
    assert_eq!(Material::default().alpha_mode, AlphaMode::Opaque);
    assert_eq!(AlphaMode::mask(), AlphaMode::Mask { cutoff: DEFAULT_ALPHA_CUTOFF });
}

#[test]
fn bad_alpha_values_are_warnings_with_defaults() {
    let cases = [
        (
            serde_json::json!({"name": "neg", "alphaMode": "MASK", "alphaCutoff": -0.5}),
            AlphaMode::mask(),
            "alphaCutoff",
        ),
        // Beyond f32: read as infinity.
        (
            serde_json::json!({"name": "huge", "alphaMode": "MASK", "alphaCutoff": 1e39}),
            AlphaMode::mask(),
            "alphaCutoff",
        ),
        (serde_json::json!({"name": "glass", "alphaMode": "GLASS"}), AlphaMode::Opaque, "alphaMode"),
    ];
    for (k, (json, want, field)) in cases.into_iter().enumerate() {
        let scene = tiny_with_material(&format!("alpha_bad{k}"), json.clone()).unwrap();
        assert_eq!(only_material(&scene).alpha_mode, want, "{json}");
        assert_eq!(scene.warnings.len(), 1, "{json}: {:?}", scene.warnings);
        assert_mentions(&scene.warnings[0], &[json["name"].as_str().unwrap(), field]);
    }
    // Not a number at all (JSON has no NaN): the file is refused, naming it; no panic.
    let e = err_text(tiny_with_material("alpha_str", serde_json::json!({"alphaMode": "MASK", "alphaCutoff": "half"})));
    assert_mentions(&e, &["m.gltf", "invalid glTF JSON"]);
    let dir = tmp_dir("alpha_nan");
    let path = tiny_gltf(&dir, "nan.gltf", &[0, 1, 2], |_| {});
    let text = std::fs::read_to_string(&path).unwrap();
    let text =
        text.replacen("\"asset\"", "\"materials\": [{\"alphaMode\": \"MASK\", \"alphaCutoff\": NaN}], \"asset\"", 1);
    std::fs::write(&path, text).unwrap();
    assert_mentions(&err_text(load(&path)), &["nan.gltf", "invalid glTF JSON"]);
}

#[test]
fn transparent_asset_materials() {
    let scene = load(asset("transparent.gltf")).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.instances().len(), 10);
    let m = |n| material_named(&scene, n);
    assert_eq!(m("wall").alpha_mode, AlphaMode::Opaque);
    // No alphaMode: opaque, its alpha kept in the factor (and ignored when drawn).
    assert_eq!((m("opaque_blue").alpha_mode, m("opaque_blue").base_color[3]), (AlphaMode::Opaque, 0.3));
    for (name, alpha) in [("red_glass", 0.6), ("green_glass", 0.4), ("blue_glass", 0.2), ("cyan_glass", 0.5)] {
        assert_eq!((m(name).alpha_mode, m(name).base_color[3]), (AlphaMode::Blend, alpha), "{name}");
    }
    assert_eq!(m("cutout").alpha_mode, AlphaMode::Mask { cutoff: 0.5 });
    let tex = m("cutout").base_color_texture.as_ref().expect("the cutout is textured");
    // Alpha 255 and 0 in 2×2-texel cells.
    assert_eq!((tex.texel(0, 0)[3], tex.texel(2, 0)[3], tex.texel(2, 2)[3]), (255, 0, 255));
    assert_eq!(m("faint_mask").alpha_mode, AlphaMode::Mask { cutoff: 0.3 });
}

#[test]
fn obj_dissolve_makes_blended_materials() {
    let dir = tmp_dir("dissolve");
    std::fs::write(
        dir.join("d.mtl"),
        "newmtl half\nKd 1 0 0\nd 0.5\nnewmtl tr\nKd 0 1 0\nTr 0.25\nnewmtl solid\nKd 0 0 1\nd 1\nnewmtl nokd\nd 0.2\n",
    )
    .unwrap();
    let mut obj = String::from("mtllib d.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
    for m in ["half", "tr", "solid", "nokd"] {
        obj += &format!("o {m}\nusemtl {m}\nf 1 2 3\n");
    }
    std::fs::write(dir.join("d.obj"), obj).unwrap();
    let scene = load(dir.join("d.obj")).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let m = |n| material_named(&scene, n);
    assert_eq!((m("half").alpha_mode, m("half").base_color), (AlphaMode::Blend, [1.0, 0.0, 0.0, 0.5]));
    assert_eq!((m("tr").alpha_mode, m("tr").base_color[3]), (AlphaMode::Blend, 0.75));
    assert_eq!((m("solid").alpha_mode, m("solid").base_color[3]), (AlphaMode::Opaque, 1.0));
    assert_eq!((m("nokd").alpha_mode, m("nokd").base_color[3]), (AlphaMode::Blend, 0.2));
    let cube = load(asset("cube.obj")).unwrap();
    assert_eq!(cube.materials().next().unwrap().1.alpha_mode, AlphaMode::Opaque);
}

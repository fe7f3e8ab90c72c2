//! glTF animation: the authored `assets/animated.gltf` played at chosen times against poses
//! worked out by hand, the player's rules (untargeted components, looping, stale targets),
//! and broken animation data, each of which must give a warning naming the animation and
//! the channel while the model still loads.

use std::path::{Path, PathBuf};

use glam::{Affine3A, Quat, Vec3};
use sightline_scene::animation::{Animation, Curve, Interpolation, Sampler, Wrap};
use sightline_scene::*;

use crate::support::{asset, tmp_dir};

fn assert_vec(got: Vec3, want: [f32; 3], what: &str) {
    let want = Vec3::from(want);
    assert!((got - want).abs().max_element() < 1e-5, "{what}: got {got}, want {want}");
}

/// The angle of a rotation about z, in degrees (the rotation must be about z).
fn z_degrees(q: Quat) -> f32 {
    let (axis, angle) = q.to_axis_angle();
    assert!(angle < 1e-6 || axis.z.abs() > 0.9999, "{q} is not about z");
    (angle * axis.z.signum()).to_degrees()
}

fn origin(scene: &Scene, name: &str) -> Vec3 {
    let id = scene.find(name).unwrap();
    scene.node(id).unwrap().world_matrix().transform_point3(Vec3::ZERO)
}

fn local(scene: &Scene, name: &str) -> Transform {
    scene.node(scene.find(name).unwrap()).unwrap().local_transform()
}

fn played(t: f32) -> Scene {
    let mut scene = load(asset("animated.gltf")).unwrap();
    assert_eq!(scene.animate(t).unwrap(), 3, "three nodes are animated");
    scene.update_transforms();
    scene
}

// ---- the authored asset -------------------------------------------------------------------

/// assets/animated.gltf, animation "wave" (duration 2 s):
///
/// base  (mesh)              translation LINEAR  t 0, 2: (0,0,0) → (4,0,0)
/// └─ arm  T(2,0,0) (mesh)    rotation LINEAR     t 0, 1, 2: Rz 0°, 90°, 180°
///    └─ hand T(0,1,0) (mesh) scale STEP          t 0, 1: 1 → 2 (uniform)
///                            translation CUBICSPLINE t 0, 2: (0,1,0) → (0,3,0),
///                              out-tangent of key 0 (1,0,0)/s, in-tangent of key 1 zero
#[test]
fn animated_gltf_loads_one_animation() {
    let scene = load(asset("animated.gltf")).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.animations().len(), 1);
    let a = &scene.animations()[0];
    assert_eq!((a.name.as_str(), a.channels.len(), a.duration(), a.wrap), ("wave", 4, 2.0, Wrap::Clamp));
    let modes: Vec<_> = a.channels.iter().map(|c| (c.curve.property().to_string(), c.curve.interpolation())).collect();
    assert_eq!(
        modes,
        [
            ("translation".into(), Interpolation::Linear),
            ("rotation".into(), Interpolation::Linear),
            ("scale".into(), Interpolation::Step),
            ("translation".into(), Interpolation::CubicSpline),
        ]
    );
    assert_eq!(scene.stats().triangles, 3);
}

#[test]
fn poses_at_half_a_second() {
    let scene = played(0.5);
    // base: LINEAR 0 → 4 over [0, 2], s = 0.25 → x = 1.
    assert_vec(local(&scene, "base").translation, [1.0, 0.0, 0.0], "base translation");
    // arm: slerp from 0° to 90° at s = 0.5 → 45°; its translation (2,0,0) is not animated.
    assert!((z_degrees(local(&scene, "arm").rotation) - 45.0).abs() < 1e-3);
    assert_vec(local(&scene, "arm").translation, [2.0, 0.0, 0.0], "arm translation kept");
    // hand: STEP holds key 0 on [0, 1) → scale 1. CUBICSPLINE, td = 2, s = 0.25:
    // h00 = 2s³ − 3s² + 1 = 0.84375, h10 = s³ − 2s² + s = 0.140625, h01 = −2s³ + 3s² = 0.15625,
    // p = 0.84375·(0,1,0) + 2·0.140625·(1,0,0) + 0.15625·(0,3,0) = (0.28125, 1.3125, 0).
    let hand = local(&scene, "hand");
    assert_vec(hand.scale, [1.0, 1.0, 1.0], "hand scale");
    assert_vec(hand.translation, [0.28125, 1.3125, 0.0], "hand translation");
    // World: arm origin = (1,0,0) + (2,0,0) = (3,0,0). The hand origin is the arm's
    // Rz(45°) applied to (0.28125, 1.3125): x = (0.28125 − 1.3125)·√½ = −0.729204,
    // y = (0.28125 + 1.3125)·√½ = 1.126951 → (2.270796, 1.126951, 0).
    assert_vec(origin(&scene, "arm"), [3.0, 0.0, 0.0], "arm world origin");
    assert_vec(origin(&scene, "hand"), [2.270796, 1.126951, 0.0], "hand world origin");
}

#[test]
fn poses_at_one_and_a_half_seconds() {
    let scene = played(1.5);
    // base x = 3. arm: slerp from 90° to 180° at s = 0.5 → 135°. hand: STEP after its last
    // key (t = 1) → scale 2. CUBICSPLINE s = 0.75: h00 = 0.15625, h10 = 0.046875,
    // h01 = 0.84375 → p = (2·0.046875, 0.15625 + 3·0.84375, 0) = (0.09375, 2.6875, 0).
    assert!((z_degrees(local(&scene, "arm").rotation) - 135.0).abs() < 1e-3);
    assert_vec(local(&scene, "hand").scale, [2.0, 2.0, 2.0], "hand scale");
    assert_vec(local(&scene, "hand").translation, [0.09375, 2.6875, 0.0], "hand translation");
    // World: arm origin (5,0,0); Rz(135°) (cos = −√½, sin = √½) of (0.09375, 2.6875):
    // x = −(0.09375 + 2.6875)·√½ = −1.966641, y = (0.09375 − 2.6875)·√½ = −1.834058.
    assert_vec(origin(&scene, "hand"), [3.033359, -1.834058, 0.0], "hand world origin");
    // The hand's world x axis: its scale 2 turned by 135° → 2·(−√½, √½, 0).
    let m: Affine3A = scene.node(scene.find("hand").unwrap()).unwrap().world_matrix();
    let r2 = std::f32::consts::SQRT_2;
    assert_vec(m.matrix3.x_axis.into(), [-r2, r2, 0.0], "hand world x axis");
}

#[test]
fn linear_rotation_is_slerp_not_normalized_lerp() {
    // At t = 0.25 slerp from 0° to 90° gives 22.5°; a normalized lerp of the quaternions
    // would give 2·atan(0.25·sin 45° / (0.75 + 0.25·cos 45°)) = 21.6°.
    let scene = played(0.25);
    assert!((z_degrees(local(&scene, "arm").rotation) - 22.5).abs() < 1e-3);
}

#[test]
fn time_outside_the_keys_is_clamped() {
    // After the last key: base (4,0,0), arm 180°, hand scale 2 at (0,3,0) → hand origin
    // (6,0,0) + Rz(180°)(0,3,0) = (6,−3,0). Before the first key: the first values →
    // hand origin (2,0,0) + (0,1,0).
    assert_vec(origin(&played(3.0), "hand"), [6.0, -3.0, 0.0], "after the end");
    assert_vec(origin(&played(-1.0), "hand"), [2.0, 1.0, 0.0], "before the start");
}

#[test]
fn looping_plays_time_modulo_the_duration() {
    let mut scene = load(asset("animated.gltf")).unwrap();
    // Played once clamped first: a change through `animations_mut` must reach the next
    // `animate` (the scene lays its animations out for playing once, and again on change).
    scene.animate(2.5).unwrap();
    scene.animations_mut()[0].wrap = Wrap::Loop;
    scene.animate(2.5).unwrap();
    scene.update_transforms();
    // 2.5 mod 2 = 0.5: the pose of poses_at_half_a_second.
    assert_vec(origin(&scene, "hand"), [2.270796, 1.126951, 0.0], "hand world origin");
}

#[test]
fn untargeted_components_keep_the_nodes_values() {
    let mut scene = load(asset("animated.gltf")).unwrap();
    let arm = scene.find("arm").unwrap();
    // The arm's rotation is animated, its translation and scale are not.
    scene
        .set_local_transform(arm, Transform::from_translation(Vec3::new(7.0, 0.0, 0.0)).with_scale(Vec3::splat(3.0)))
        .unwrap();
    scene.animate(1.0).unwrap();
    let t = scene.node(arm).unwrap().local_transform();
    assert_vec(t.translation, [7.0, 0.0, 0.0], "arm translation");
    assert_vec(t.scale, [3.0, 3.0, 3.0], "arm scale");
    assert!((z_degrees(t.rotation) - 90.0).abs() < 1e-3);
    assert!(scene.node(arm).unwrap().is_dirty(), "animate marks the node dirty");
}

/// A mirrored node (scale (1, −1, 1)) whose rotation is animated keeps its mirrored axis:
/// the scene keeps the TRS it was given, where a matrix would put the sign on x.
#[test]
fn a_mirrored_node_keeps_its_mirrored_axis() {
    let mut scene = Scene::new();
    let wheel = scene
        .add_node(None, NodeDesc::new("wheel").transform(Transform::from_scale(Vec3::new(1.0, -1.0, 1.0))))
        .unwrap();
    let spin =
        Sampler::new(vec![0.0, 1.0], vec![Quat::IDENTITY, Quat::from_rotation_y(0.5)], Interpolation::Linear).unwrap();
    scene.add_animation(Animation::new("spin").with_channel(wheel, Curve::Rotation(spin)));
    for t in [0.0, 0.5, 1.0, 0.0] {
        scene.animate(t).unwrap();
    }
    // At t = 0: rotation identity, so the matrix is diag(1, −1, 1), not diag(−1, 1, 1).
    let m = scene.node(wheel).unwrap().local_matrix();
    assert_eq!(m, Affine3A::from_scale(Vec3::new(1.0, -1.0, 1.0)));
    assert_eq!(scene.local_transform(wheel).unwrap().scale, Vec3::new(1.0, -1.0, 1.0));
}

/// A scale animated through zero with a translation channel and no rotation channel: the
/// node keeps its own rotation (a matrix of zero scale has none to give back), with no error.
#[test]
fn a_scale_through_zero_keeps_the_nodes_rotation() {
    let mut scene = Scene::new();
    let turned = Transform::from_rotation(Quat::from_rotation_y(std::f32::consts::FRAC_PI_2));
    let node = scene.add_node(None, NodeDesc::new("popper").transform(turned)).unwrap();
    let grow = Sampler::new(vec![0.0, 1.0], vec![Vec3::ZERO, Vec3::ONE], Interpolation::Linear).unwrap();
    let slide = Sampler::new(vec![0.0, 1.0], vec![Vec3::ZERO, Vec3::X], Interpolation::Linear).unwrap();
    scene.add_animation(
        Animation::new("pop").with_channel(node, Curve::Scale(grow)).with_channel(node, Curve::Translation(slide)),
    );
    scene.animate(0.0).unwrap();
    scene.animate(0.5).unwrap();
    let t = scene.local_transform(node).unwrap();
    assert_vec(t.scale, [0.5, 0.5, 0.5], "scale");
    assert_vec(t.translation, [0.5, 0.0, 0.0], "translation");
    assert!(t.rotation.angle_between(turned.rotation) < 1e-6, "the rotation is kept: {}", t.rotation);
    // Taken apart from the matrix alone, a zero scale gives a finite rotation too.
    let flat = Transform::from_affine(&Affine3A::from_scale(Vec3::new(0.0, 2.0, 2.0)));
    assert!(flat.rotation.is_finite() && flat.scale == Vec3::new(0.0, 2.0, 2.0), "{flat:?}");
}

#[test]
fn non_finite_time_is_an_error() {
    let mut scene = load(asset("animated.gltf")).unwrap();
    let e = scene.animate(f32::NAN).unwrap_err().to_string();
    assert!(e.contains("wave") && e.contains("not finite"), "{e}");
}

// ---- animations made in code --------------------------------------------------------------

#[test]
fn a_removed_target_is_reported_and_can_be_dropped() {
    let mut scene = Scene::new();
    let a = scene.add_node(None, NodeDesc::new("a")).unwrap();
    let b = scene.add_node(None, NodeDesc::new("b")).unwrap();
    let up = Sampler::new(vec![0.0, 1.0], vec![Vec3::ZERO, Vec3::Y], Interpolation::Linear).unwrap();
    scene.add_animation(
        Animation::new("lift")
            .with_channel(a, Curve::Translation(up.clone()))
            .with_channel(b, Curve::Translation(up.clone())),
    );
    // Removing a node removes the channels aimed at it; the others play on.
    scene.remove_node(a).unwrap();
    assert_eq!(scene.animate(0.5).unwrap(), 1);
    assert_vec(scene.node(b).unwrap().local_transform().translation, [0.0, 0.5, 0.0], "b");
    // A channel aimed at a stale handle afterwards is reported, and can be dropped.
    scene.add_animation(Animation::new("late").with_channel(a, Curve::Translation(up)));
    let e = scene.animate(0.5).unwrap_err().to_string();
    assert!(e.contains("'late'") && e.contains("channel 0 (translation)"), "{e}");
    assert_eq!(scene.drop_dead_animation_channels(), 1);
    assert_eq!(scene.animate(1.0).unwrap(), 1);
}

#[test]
fn apply_plays_one_animation_as_animate_does() {
    // One animation applied by itself sets the very bits `Scene::animate` sets, at times in
    // and outside its keys.
    for t in [0.0, 0.37, 1.0, 1.5, 2.0, 5.0] {
        let mut by_scene = load(asset("animated.gltf")).unwrap();
        by_scene.animate(t).unwrap();
        let mut by_apply = load(asset("animated.gltf")).unwrap();
        let wave = by_apply.animations()[0].clone();
        assert_eq!(wave.apply(&mut by_apply, t).unwrap(), 3);
        for name in ["base", "arm", "hand"] {
            let (a, b) = (local(&by_scene, name), local(&by_apply, name));
            assert_eq!(
                (a.translation.to_array(), a.rotation.to_array(), a.scale.to_array()),
                (b.translation.to_array(), b.rotation.to_array(), b.scale.to_array()),
                "{name} at {t}"
            );
        }
    }
    // A channel aimed at a removed node is named; the other channels still play.
    let mut scene = load(asset("animated.gltf")).unwrap();
    let wave = scene.animations()[0].clone();
    let hand = scene.find("hand").unwrap();
    scene.remove_node(hand).unwrap();
    let e = wave.apply(&mut scene, 1.0).unwrap_err().to_string();
    assert!(e.contains("wave") && e.contains("channel"), "{e}");
    assert!((z_degrees(local(&scene, "arm").rotation) - 90.0).abs() < 1e-3, "the arm still turned");
    assert!(wave.apply(&mut scene, f32::INFINITY).unwrap_err().to_string().contains("not finite"));
}

/// Removing animated nodes one by one leaves their channels until the next `animate`, which
/// drops them all in one pass (a pass per removal would be quadratic in the node count).
#[test]
fn channels_of_removed_nodes_go_at_the_next_animate() {
    let mut scene = Scene::new();
    let up = Sampler::new(vec![0.0, 1.0], vec![Vec3::ZERO, Vec3::Y], Interpolation::Linear).unwrap();
    let nodes: Vec<NodeId> = (0..2000).map(|i| scene.add_node(None, NodeDesc::new(format!("n{i}"))).unwrap()).collect();
    for (i, &n) in nodes.iter().enumerate() {
        scene.add_animation(Animation::new(format!("a{i}")).with_channel(n, Curve::Translation(up.clone())));
    }
    for &n in nodes.iter().step_by(2) {
        scene.remove_node(n).unwrap();
    }
    assert_eq!(scene.animations().len(), 2000, "still listed until the next animate");
    assert_eq!(scene.animate(0.5).unwrap(), 1000, "the survivors play, with no error for the removed");
    assert_eq!(scene.animations().len(), 1000);
}

// ---- broken animation data ----------------------------------------------------------------

/// A glTF with one triangle on node 0 ("holder") and animation 0 ("ok") whose channel 0
/// moves it (times 0, 1, 2); `edit` adds the broken parts. Buffer data goes in a
/// percent-encoded data URI.
fn anim_gltf(dir: &Path, name: &str, edit: impl FnOnce(&mut serde_json::Value)) -> PathBuf {
    let mut buf: Vec<u8> = Vec::new();
    let mut f = |xs: &[f32]| -> (usize, usize) {
        let at = buf.len();
        for x in xs {
            buf.extend(x.to_le_bytes());
        }
        (at, 4 * xs.len())
    };
    let views = [
        f(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]),      // 0: positions
        f(&[0.0, 1.0, 2.0]),                                    // 1: times
        f(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0]),      // 2: three VEC3 values
        f(&[0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0, 2.0, 0.0, 0.0]), // 3: a NaN value
        f(&[0.0, 1.0, 1.0]),                                    // 4: times not increasing
    ];
    let uri: String = buf.iter().map(|b| format!("%{b:02X}")).collect();
    let mut doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "holder", "mesh": 0}, {"name": "elsewhere"}],
        "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 4, "componentType": 5126, "count": 3, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5126, "count": 2, "type": "VEC3"}
        ],
        "bufferViews": views.iter().map(|&(o, l)| serde_json::json!({"buffer": 0, "byteOffset": o, "byteLength": l})).collect::<Vec<_>>(),
        "buffers": [{"byteLength": buf.len(), "uri": format!("data:application/octet-stream,{uri}")}],
        "animations": [{
            "name": "ok",
            "samplers": [{"input": 1, "output": 2}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}]
        }]
    });
    edit(&mut doc);
    let path = dir.join(name);
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    path
}

/// Adds sampler `{input, output}` and a channel using it aimed at `node`'s `path` to
/// animation 0 (as its channel 1).
fn add_channel(doc: &mut serde_json::Value, input: u32, output: u32, node: u32, path: &str) {
    let a = &mut doc["animations"][0];
    let s = a["samplers"].as_array().unwrap().len();
    a["samplers"].as_array_mut().unwrap().push(serde_json::json!({"input": input, "output": output}));
    a["channels"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"sampler": s, "target": {"node": node, "path": path}}));
}

/// Loads the file, checks that the model and the good channel survived, and returns the
/// one warning.
fn the_warning(test: &str, edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let dir = tmp_dir(&format!("anim-{test}"));
    let scene = load(anim_gltf(&dir, &format!("{test}.gltf"), edit)).unwrap();
    assert_eq!(scene.stats().triangles, 1, "the model still loads");
    assert_eq!(scene.animations().len(), 1);
    assert_eq!(scene.animations()[0].channels.len(), 1, "only the good channel is kept");
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    let w = scene.warnings[0].clone();
    assert!(w.contains(&format!("{test}.gltf")), "{w}");
    w
}

fn assert_names_channel_1(w: &str, parts: &[&str]) {
    assert!(w.contains("animation 0 ('ok') channel 1"), "{w}");
    for p in parts {
        assert!(w.contains(p), "warning {w:?} does not mention {p:?}");
    }
}

#[test]
fn the_good_file_has_no_warning() {
    let dir = tmp_dir("anim-good");
    let scene = load(anim_gltf(&dir, "good.gltf", |_| {})).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.animations()[0].duration(), 2.0);
}

#[test]
fn input_and_output_counts_that_disagree_skip_the_channel() {
    let w = the_warning("counts", |d| add_channel(d, 1, 5, 0, "scale"));
    assert_names_channel_1(&w, &["scale of node 0 ('holder')", "3 keys need 3 output values", "has 2"]);
}

#[test]
fn times_not_increasing_skip_the_channel() {
    let w = the_warning("times", |d| add_channel(d, 4, 2, 0, "scale"));
    assert_names_channel_1(&w, &["strictly increasing", "time 2 is 1 after time 1 = 1"]);
}

#[test]
fn a_nan_keyframe_skips_the_channel() {
    let w = the_warning("nan", |d| add_channel(d, 1, 3, 0, "translation"));
    assert_names_channel_1(&w, &["translation of node 0", "output value 1", "not finite"]);
}

#[test]
fn a_missing_target_node_skips_the_channel() {
    let w = the_warning("missing", |d| add_channel(d, 1, 2, 9, "translation"));
    assert_names_channel_1(&w, &["node 9 does not exist"]);
    // A node that exists but is not in the loaded scene.
    let w = the_warning("elsewhere", |d| add_channel(d, 1, 2, 1, "translation"));
    assert_names_channel_1(&w, &["node 1 ('elsewhere') is not in the loaded scene"]);
}

#[test]
fn other_bad_channels_skip_the_channel() {
    let w = the_warning("sampler", |d| {
        d["animations"][0]["channels"]
            .as_array_mut()
            .unwrap()
            .push(serde_json::json!({"sampler": 7, "target": {"node": 0, "path": "scale"}}))
    });
    assert_names_channel_1(&w, &["sampler 7 does not exist"]);
    let w = the_warning("rotation-type", |d| add_channel(d, 1, 2, 0, "rotation"));
    assert_names_channel_1(&w, &["rotation of node 0", "animation output accessor 2 has type Vec3"]);
    let w = the_warning("interp", |d| {
        add_channel(d, 1, 2, 0, "scale");
        d["animations"][0]["samplers"][1]["interpolation"] = "CUBICSPLINE".into();
    });
    assert_names_channel_1(&w, &["3 keys need 9 output values with CUBICSPLINE"]);
}

#[test]
fn morph_weights_skins_and_morph_targets_are_warned_about() {
    let w = the_warning("weights", |d| add_channel(d, 1, 2, 0, "weights"));
    assert_names_channel_1(&w, &["weights of node 0", "morph target weights are not animated"]);
    let w = the_warning("skin", |d| {
        d["nodes"][0]["skin"] = 0.into();
        d["skins"] = serde_json::json!([{"joints": [0]}]);
    });
    assert!(w.contains("1 skinned node(s) drawn in the bind pose") && w.contains("node 0 ('holder')"), "{w}");
    let w = the_warning("morph", |d| {
        d["meshes"][0]["primitives"][0]["targets"] = serde_json::json!([{"POSITION": 0}]);
    });
    assert!(w.contains("1 mesh(es) with morph targets drawn in the bind pose") && w.contains("mesh 0 ('tri')"), "{w}");
}

// ---- copies ---------------------------------------------------------------------------------

/// A placed animated model moves like the original: a prefab of the asset placed twice, and
/// a copy of its `base` subtree made by `instantiate`, each pose at t = 0.5 s equals the
/// original's (local transforms), while the copies stay independent nodes.
#[test]
fn copies_of_an_animated_model_play_its_animation() {
    let t = 0.5;
    let reference = played(t);
    let want = |name: &str| local(&reference, name);
    let mut scene = Scene::new();
    let prefab = load_prefab(&mut scene, asset("animated.gltf"), &LoadOptions::default()).unwrap();
    let a = scene.instantiate_prefab(&prefab, None, Transform::from_translation(Vec3::X * 10.0)).unwrap();
    let b = scene.instantiate_prefab(&prefab, None, Transform::from_translation(Vec3::X * 20.0)).unwrap();
    assert_eq!(scene.animations().len(), 2, "one animation per placement");
    // A copy of one placement's `base` subtree, made in the scene.
    let base_of = |scene: &Scene, root: NodeId| {
        let mut stack = vec![root];
        while let Some(n) = stack.pop() {
            let node = scene.node(n).unwrap();
            if node.name() == "base" {
                return n;
            }
            stack.extend(node.children());
        }
        panic!("no base under the placement");
    };
    let base_a = base_of(&scene, a);
    let copy = scene.instantiate(base_a, None, Transform::default()).unwrap();
    assert_eq!(scene.animations().len(), 3, "the copy got its own channels");
    assert_eq!(scene.animate(t).unwrap(), 9, "three nodes in each of three copies");
    scene.update_transforms();
    for root in [a, b] {
        let base = base_of(&scene, root);
        let arm = scene.node(base).unwrap().children().next().unwrap();
        let hand = scene.node(arm).unwrap().children().next().unwrap();
        for (id, name) in [(base, "base"), (arm, "arm"), (hand, "hand")] {
            let got = scene.node(id).unwrap().local_transform();
            assert_vec(got.translation, want(name).translation.into(), name);
            assert!(got.rotation.angle_between(want(name).rotation) < 1e-5, "{name}");
        }
    }
    // `instantiate` replaces the copy root's transform, but the animation sets it again.
    let got = scene.node(copy).unwrap().local_transform();
    assert_vec(got.translation, want("base").translation.into(), "copied base");
    let arm = scene.node(copy).unwrap().children().next().unwrap();
    assert!(scene.node(arm).unwrap().local_transform().rotation.angle_between(want("arm").rotation) < 1e-5);
    // Removing a copy drops its channels only.
    scene.remove_node(copy).unwrap();
    assert_eq!(scene.animate(t).unwrap(), 6);
}

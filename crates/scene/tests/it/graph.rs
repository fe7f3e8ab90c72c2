//! Scene graph behaviour: propagation, reparenting, removal, inheritance, bad input.

use glam::{Affine3A, Quat, Vec3};
use sightline_scene::*;

fn approx(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-4
}

#[test]
fn world_transforms_compose_down_the_tree() {
    let mut s = Scene::new();
    let a = s.add_node(None, NodeDesc::new("a").transform(Transform::from_translation(Vec3::X * 10.0))).unwrap();
    let b = s
        .add_node(
            Some(a),
            NodeDesc::new("b").transform(Transform::from_rotation(Quat::from_rotation_y(std::f32::consts::FRAC_PI_2))),
        )
        .unwrap();
    let c = s
        .add_node(
            Some(b),
            NodeDesc::new("c").transform(Transform::from_translation(Vec3::X).with_scale(Vec3::new(2.0, 1.0, 1.0))),
        )
        .unwrap();
    s.update_transforms();
    // c's origin: b rotates +x to −z, so (1,0,0) → (0,0,−1), then + (10,0,0).
    let w = s.node(c).unwrap().world_matrix();
    assert!(approx(w.transform_point3(Vec3::ZERO), Vec3::new(10.0, 0.0, -1.0)));
    // c's local x axis is scaled by 2 and rotated to −z.
    assert!(approx(w.transform_vector3(Vec3::X), Vec3::new(0.0, 0.0, -2.0)));
}

#[test]
fn incremental_update_visits_only_dirty_subtrees() {
    let mut s = Scene::new();
    let root = s.add_node(None, NodeDesc::new("root")).unwrap();
    let groups: Vec<_> = (0..10).map(|i| s.add_node(Some(root), NodeDesc::new(format!("g{i}"))).unwrap()).collect();
    for &g in &groups {
        for j in 0..9 {
            s.add_node(Some(g), NodeDesc::new(format!("leaf{j}"))).unwrap();
        }
    }
    assert_eq!(s.update_transforms(), 101);
    assert_eq!(s.update_transforms(), 0, "nothing changed");
    s.set_local_transform(groups[3], Transform::from_translation(Vec3::Y)).unwrap();
    assert_eq!(s.update_transforms(), 10, "one group and its nine leaves");
    let leaf = s.node(groups[3]).unwrap().children().next().unwrap();
    assert!(approx(s.node(leaf).unwrap().world_matrix().translation.into(), Vec3::Y));
    // A dirty child under a dirty parent is handled once.
    s.set_local_transform(leaf, Transform::from_translation(Vec3::X)).unwrap();
    s.set_local_transform(groups[3], Transform::from_translation(Vec3::Z)).unwrap();
    assert_eq!(s.update_transforms(), 10);
    assert!(approx(s.node(leaf).unwrap().world_matrix().translation.into(), Vec3::new(1.0, 0.0, 1.0)));
}

#[test]
fn a_chain_100000_deep_propagates_without_recursion() {
    let mut s = Scene::new();
    let mut parent = None;
    let mut first = None;
    for _ in 0..100_000 {
        let id =
            s.add_node(parent, NodeDesc::new("link").transform(Transform::from_translation(Vec3::Y * 0.5))).unwrap();
        first.get_or_insert(id);
        parent = Some(id);
    }
    // Run in a thread with a small stack to prove no recursion.
    let handle = std::thread::Builder::new()
        .stack_size(256 * 1024)
        .spawn(move || {
            assert_eq!(s.update_transforms(), 100_000);
            let last = parent.unwrap();
            let y = s.node(last).unwrap().world_matrix().translation.y;
            assert!((y - 50_000.0).abs() < 1.0, "{y}");
            s.set_local_transform(first.unwrap(), Transform::from_translation(Vec3::Y * 1.5)).unwrap();
            assert_eq!(s.update_transforms(), 100_000);
            let instances = s.instances();
            assert!(instances.is_empty());
            assert_eq!(s.depth_first().count(), 100_000);
            assert_eq!(s.remove_node(first.unwrap()).unwrap().nodes, 100_000);
        })
        .unwrap();
    handle.join().unwrap();
}

#[test]
fn reparent_keeps_world_or_local_as_asked() {
    let mut s = Scene::new();
    let a =
        s.add_node(None, NodeDesc::new("a").transform(Transform::from_translation(Vec3::new(5.0, 0.0, 0.0)))).unwrap();
    let b = s
        .add_node(
            None,
            NodeDesc::new("b").transform(
                Transform::from_translation(Vec3::new(0.0, 3.0, 0.0))
                    .with_rotation(Quat::from_rotation_z(0.7))
                    .with_scale(Vec3::new(2.0, 2.0, 2.0)),
            ),
        )
        .unwrap();
    let c = s
        .add_node(Some(a), NodeDesc::new("c").transform(Transform::from_translation(Vec3::new(1.0, 1.0, 1.0))))
        .unwrap();
    s.update_transforms();
    let before = s.node(c).unwrap().world_matrix();
    s.set_parent(c, Some(b), Keep::World).unwrap();
    s.update_transforms();
    let after = s.node(c).unwrap().world_matrix();
    assert!(approx(after.transform_point3(Vec3::ZERO), before.transform_point3(Vec3::ZERO)));
    assert!(approx(after.transform_vector3(Vec3::X), before.transform_vector3(Vec3::X)));
    assert_eq!(s.node(c).unwrap().parent(), Some(b));
    assert_eq!(s.node(c).unwrap().depth(), 1);
    // Keep local: the node moves with its new parent.
    s.set_parent(c, Some(a), Keep::Local).unwrap();
    s.update_transforms();
    let local = s.node(c).unwrap().local_matrix();
    assert!(approx(
        s.node(c).unwrap().world_matrix().translation.into(),
        Vec3::X * 5.0 + Vec3::from(local.translation)
    ));
    // Make it a root, keeping world.
    s.set_parent(c, None, Keep::World).unwrap();
    assert!(s.roots().any(|r| r == c));
}

#[test]
fn cycles_are_refused() {
    let mut s = Scene::new();
    let a = s.add_node(None, NodeDesc::new("a")).unwrap();
    let b = s.add_node(Some(a), NodeDesc::new("b")).unwrap();
    let c = s.add_node(Some(b), NodeDesc::new("c")).unwrap();
    let e = s.set_parent(a, Some(c), Keep::Local).unwrap_err();
    assert!(matches!(e, Error::Cycle { .. }) && e.to_string().contains("cycle"), "{e}");
    assert!(e.to_string().contains("node 'a' under node 'c'"), "the error names both nodes: {e}");
    assert!(s.set_parent(a, Some(a), Keep::World).is_err());
    assert_eq!(s.node(a).unwrap().parent(), None, "a failed reparent changes nothing");
}

#[test]
fn removing_a_subtree_invalidates_exactly_its_handles() {
    let mut s = Scene::new();
    let root = s.add_node(None, NodeDesc::new("root")).unwrap();
    let keep = s.add_node(Some(root), NodeDesc::new("keep")).unwrap();
    let gone = s.add_node(Some(root), NodeDesc::new("gone")).unwrap();
    let gone_kids: Vec<_> = (0..5).map(|i| s.add_node(Some(gone), NodeDesc::new(format!("k{i}"))).unwrap()).collect();
    let grandkid = s.add_node(Some(gone_kids[2]), NodeDesc::new("gk")).unwrap();
    let keep_kid = s.add_node(Some(keep), NodeDesc::new("kk")).unwrap();
    assert_eq!(s.remove_node(gone).unwrap().nodes, 7);
    for id in gone_kids.iter().chain([&gone, &grandkid]) {
        assert!(s.node(*id).is_none());
        assert!(matches!(s.try_node(*id), Err(Error::StaleNode(_))));
        assert!(s.set_local_transform(*id, Transform::IDENTITY).is_err());
        assert!(s.remove_node(*id).is_err());
    }
    for id in [root, keep, keep_kid] {
        assert!(s.node(id).is_some());
    }
    assert_eq!(s.node(root).unwrap().children().collect::<Vec<_>>(), [keep]);
    // New nodes never reuse a stale handle's identity.
    let fresh = s.add_node(None, NodeDesc::new("fresh")).unwrap();
    assert!(![gone, grandkid].contains(&fresh));
    assert!(s.node(gone).is_none());
    assert_eq!(s.update_transforms(), 4);
}

#[test]
fn materials_are_inherited_unless_overridden() {
    let mut s = Scene::new();
    let m = s.add_mesh(shapes::cube("c").unwrap());
    let red = s.add_material(Material::color("red", [1.0, 0.0, 0.0]));
    let blue = s.add_material(Material::color("blue", [0.0, 0.0, 1.0]));
    let g = s.add_node(None, NodeDesc::new("g").material(red)).unwrap();
    let mid = s.add_node(Some(g), NodeDesc::new("mid")).unwrap();
    s.add_node(Some(mid), NodeDesc::new("a").mesh(m)).unwrap();
    let b = s.add_node(Some(mid), NodeDesc::new("b").mesh(m).material(blue)).unwrap();
    s.add_node(None, NodeDesc::new("plain").mesh(m)).unwrap();
    s.update_transforms();
    let inst = s.instances();
    assert_eq!(inst.iter().map(|i| i.material).collect::<Vec<_>>(), vec![Some(red), Some(blue), None]);
    assert_eq!(inst.iter().map(|i| i.first_triangle).collect::<Vec<_>>(), vec![0, 12, 24]);
    assert_eq!(inst[1].node, b);
    // Instancing: one mesh, three draws.
    assert!(inst.iter().all(|i| i.mesh == m));
    // What each is drawn with: its own or inherited material, else the shared fallback.
    let names: Vec<&str> = inst.iter().map(|i| s.instance_material(i).name.as_str()).collect();
    assert_eq!(names, ["red", "blue", "default"]);
    assert!(std::ptr::eq(s.instance_material(&inst[2]), Material::fallback()));
    assert_eq!(*Material::fallback(), Material::default());
    // A handle this scene never gave (another scene's third material) falls back too.
    let mut other = Scene::new();
    let foreign = (0..3).map(|k| other.add_material(Material::color(format!("o{k}"), [0.5; 3]))).last();
    let stray = sightline_scene::Instance { material: foreign, ..inst[0] };
    assert!(std::ptr::eq(s.instance_material(&stray), Material::fallback()));
}

#[test]
fn world_aabb_follows_the_node() {
    let mut s = Scene::new();
    let m = s.add_mesh(shapes::cube("c").unwrap());
    let n = s
        .add_node(
            None,
            NodeDesc::new("n").mesh(m).transform(
                Transform::from_translation(Vec3::new(0.0, 10.0, 0.0))
                    .with_rotation(Quat::from_rotation_y(std::f32::consts::FRAC_PI_4)),
            ),
        )
        .unwrap();
    s.update_transforms();
    let b = s.node(n).unwrap().world_aabb();
    let h = 0.5 * 2f32.sqrt();
    assert!(approx(b.min, Vec3::new(-h, 9.5, -h)) && approx(b.max, Vec3::new(h, 10.5, h)), "{b:?}");
}

#[test]
fn bad_transforms_are_errors_naming_the_node() {
    let mut s = Scene::new();
    let a = s.add_node(None, NodeDesc::new("lamp")).unwrap();
    let e = s.set_local_transform(a, Transform::from_translation(Vec3::new(f32::NAN, 0.0, 0.0))).unwrap_err();
    assert!(e.to_string().contains("NaN") && e.to_string().contains("lamp"), "{e}");
    let e = s.set_local_matrix(a, Affine3A::from_scale(Vec3::splat(f32::INFINITY))).unwrap_err();
    assert!(e.to_string().contains("lamp"), "{e}");
    let e = s.add_node(None, NodeDesc::new("bad").matrix(Affine3A::from_translation(Vec3::NAN))).unwrap_err();
    assert!(e.to_string().contains("bad"), "{e}");
    assert!(s.set_local_transform(a, Transform::from_rotation(Quat::from_xyzw(0.0, 0.0, 0.0, 0.0))).is_err());
    // Keeping the world transform under a singular parent cannot work.
    let flat =
        s.add_node(None, NodeDesc::new("flat").transform(Transform::from_scale(Vec3::new(1.0, 0.0, 1.0)))).unwrap();
    assert!(s.set_parent(a, Some(flat), Keep::World).is_err());
    assert!(s.set_parent(a, Some(flat), Keep::Local).is_ok());
}

/// The TRS a node keeps is the one given with its rotation made unit, whether the node had
/// none yet (the first set) or one to overwrite (every set after).
#[test]
fn the_kept_trs_has_a_unit_rotation_on_every_set() {
    let mut s = Scene::new();
    let a = s.add_node(None, NodeDesc::new("arm")).unwrap();
    let unit = Quat::from_rotation_y(0.7);
    for k in 1..=3 {
        let t = Transform::from_translation(Vec3::splat(k as f32)).with_scale(Vec3::splat(2.0));
        s.set_local_transform(a, Transform { rotation: unit * (2.0 * k as f32), ..t }).unwrap();
        let kept = s.local_transform(a).unwrap();
        assert!((kept.rotation.length() - 1.0).abs() < 1e-6, "set {k}: {:?}", kept.rotation);
        assert!(kept.rotation.abs_diff_eq(unit, 1e-6) && kept.translation == t.translation && kept.scale == t.scale);
    }
}

/// Removing a batch equals removing its nodes one by one: the survivors keep their order
/// (and so their triangle IDs); nested and repeated handles are fine; a stale one removes
/// nothing.
#[test]
fn removing_a_batch_equals_removing_one_by_one() {
    let build = || {
        let mut s = Scene::new();
        let cube = s.add_mesh(shapes::cube("cube").unwrap());
        let root = s.add_node(None, NodeDesc::new("root")).unwrap();
        let kids: Vec<NodeId> =
            (0..50).map(|i| s.add_node(Some(root), NodeDesc::new(format!("k{i}")).mesh(cube)).unwrap()).collect();
        let grandkid = s.add_node(Some(kids[7]), NodeDesc::new("g").mesh(cube)).unwrap();
        s.update_transforms();
        (s, kids, grandkid)
    };
    let (mut one, kids, _) = build();
    let (mut batch, kids_b, grandkid_b) = build();
    let doomed: Vec<usize> = (0..50).filter(|i| i % 3 == 0 || *i == 7).collect();
    let mut n = 0;
    for &i in &doomed {
        n += one.remove_node(kids[i]).unwrap().nodes;
    }
    let mut list: Vec<NodeId> = doomed.iter().map(|&i| kids_b[i]).collect();
    list.push(grandkid_b); // inside a removed subtree
    list.push(kids_b[3]); // repeated
    assert_eq!(batch.remove_nodes(&list).unwrap().nodes, n);
    one.update_transforms();
    batch.update_transforms();
    let names = |s: &Scene| {
        s.instances().iter().map(|i| (s.node(i.node).unwrap().name().to_string(), i.first_triangle)).collect::<Vec<_>>()
    };
    assert_eq!(names(&one), names(&batch));
    // A stale handle: nothing is removed.
    let count = batch.node_count();
    assert!(matches!(batch.remove_nodes(&[kids_b[1], kids_b[0]]), Err(Error::StaleNode(_))));
    assert_eq!(batch.node_count(), count);
}

/// Removing the children of one parent one at a time costs O(1) each (a removed child's
/// place is left empty and the list compacted when half of it is): 10^5 children, removed
/// first to last, used to shift the whole list each time. Interleaved with adds, removals
/// (one at a time and in batches, of children and of roots), moves between parents keeping
/// the local or the world transform, parents moving, and updates, every child list, the
/// roots, the world positions and the flattened order (triangle IDs) stay those of a plain
/// list model.
#[test]
fn child_lists_follow_removals_adds_and_moves_in_order() {
    let mut s = Scene::new();
    let root = s.add_node(None, NodeDesc::new("root")).unwrap();
    let kids: Vec<NodeId> =
        (0..100_000).map(|i| s.add_node(Some(root), NodeDesc::new(format!("k{i}"))).unwrap()).collect();
    for &k in &kids {
        s.remove_node(k).unwrap();
    }
    assert_eq!(s.node(root).unwrap().children().count(), 0);
    assert_eq!(s.node_count(), 1);

    // The model: each parent's translation and children (with their local translations),
    // and the extra roots after `root`, in order. Everything is a translation, so a world
    // position is a parent's translation plus a local one.
    let cube = s.add_mesh(shapes::cube("cube").unwrap());
    let at = |x: f32| Transform::from_translation(Vec3::new(x, 0.0, 0.0));
    let parents: Vec<NodeId> = (0..4)
        .map(|i| s.add_node(Some(root), NodeDesc::new(format!("p{i}")).transform(at(i as f32))).unwrap())
        .collect();
    let mut place: Vec<f32> = (0..4).map(|i| i as f32).collect();
    let mut model: Vec<Vec<(NodeId, f32)>> = vec![Vec::new(); parents.len()];
    let mut roots: Vec<NodeId> = vec![root];
    let mut rng = rng::Rng::new(99);
    for step in 0..8000u32 {
        let p = rng.below(parents.len() as u32) as usize;
        let x = (step % 50) as f32;
        match rng.below(14) {
            0..=3 => {
                let n = s
                    .add_node(Some(parents[p]), NodeDesc::new(format!("n{step}")).transform(at(x)).mesh(cube))
                    .unwrap();
                model[p].push((n, x));
            }
            4..=5 if !model[p].is_empty() => {
                let k = rng.below(model[p].len() as u32) as usize;
                s.remove_node(model[p].remove(k).0).unwrap();
            }
            6 if model[p].len() > 2 => {
                // A batch: two children, one of them named twice.
                let (a, b) = (model[p].remove(0).0, model[p].remove(1).0);
                s.remove_nodes(&[b, a, b]).unwrap();
            }
            7..=8 if !model[p].is_empty() => {
                let k = rng.below(model[p].len() as u32) as usize;
                let to = rng.below(parents.len() as u32) as usize;
                let (n, local) = model[p].remove(k);
                let keep_world = rng.below(2) == 0;
                s.set_parent(n, Some(parents[to]), if keep_world { Keep::World } else { Keep::Local }).unwrap();
                // Keeping the world position needs the world matrices as of now.
                let local = if keep_world { place[p] + local - place[to] } else { local };
                model[to].push((n, local));
            }
            9 => {
                place[p] = x;
                s.set_local_transform(parents[p], at(x)).unwrap();
            }
            10 => roots.push(s.add_node(None, NodeDesc::new(format!("r{step}")).mesh(cube)).unwrap()),
            11 if roots.len() > 1 => {
                let k = 1 + rng.below(roots.len() as u32 - 1) as usize;
                s.remove_node(roots.remove(k)).unwrap();
            }
            _ => {
                s.update_transforms();
            }
        }
        // Keep::World reads world matrices: keep them current.
        s.update_transforms();
        if step % 97 == 0 {
            for (p, want) in parents.iter().zip(&model) {
                let want: Vec<NodeId> = want.iter().map(|c| c.0).collect();
                assert_eq!(s.node(*p).unwrap().children().collect::<Vec<_>>(), want, "step {step}");
            }
            assert_eq!(s.roots().collect::<Vec<_>>(), roots, "step {step}");
        }
    }
    // Instances in depth-first order, with first triangles counted up from 0, where the
    // model puts them.
    let want: Vec<(NodeId, u32, f32)> = model
        .iter()
        .enumerate()
        .flat_map(|(p, kids)| kids.iter().map(move |&(n, local)| (n, p, local)))
        .chain(roots[1..].iter().map(|&r| (r, usize::MAX, 0.0)))
        .enumerate()
        .map(|(k, (n, p, local))| (n, 12 * k as u32, if p == usize::MAX { 0.0 } else { place[p] + local }))
        .collect();
    let got = s.instances();
    assert_eq!(got.len(), want.len());
    for (i, (n, first, x)) in got.iter().zip(&want) {
        assert_eq!((i.node, i.first_triangle), (*n, *first));
        assert!((i.world_from_local.translation.x - x).abs() < 1e-3, "{} vs {x}", i.world_from_local.translation.x);
    }
    assert_eq!(s.depth_first().count(), roots.len() + parents.len() + got.len() - (roots.len() - 1));
}

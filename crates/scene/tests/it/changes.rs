//! Change reports: what each kind of edit puts in `Scene::changes`, the revision protocol,
//! cameras on removed nodes.

use glam::{Quat, Vec3};
use sightline_scene::*;

/// A scene: root group "g" (red) with drawn children "a" (inherits) and "b" (blue), a group
/// "h" holding drawn "c", and a drawn root "d"; propagated.
struct Fixture {
    s: Scene,
    cube: MeshId,
    red: MaterialId,
    blue: MaterialId,
    g: NodeId,
    a: NodeId,
    b: NodeId,
    h: NodeId,
    c: NodeId,
    d: NodeId,
}

fn fixture() -> Fixture {
    let mut s = Scene::new();
    let cube = s.add_mesh(shapes::cube("cube").unwrap());
    let red = s.add_material(Material::color("red", [1.0, 0.0, 0.0]));
    let blue = s.add_material(Material::color("blue", [0.0, 0.0, 1.0]));
    let g = s.add_node(None, NodeDesc::new("g").material(red)).unwrap();
    let a = s.add_node(Some(g), NodeDesc::new("a").mesh(cube)).unwrap();
    let b = s.add_node(Some(g), NodeDesc::new("b").mesh(cube).material(blue)).unwrap();
    let h = s.add_node(Some(g), NodeDesc::new("h")).unwrap();
    let c = s.add_node(Some(h), NodeDesc::new("c").mesh(cube)).unwrap();
    let d = s.add_node(None, NodeDesc::new("d").mesh(cube)).unwrap();
    s.update_transforms();
    Fixture { s, cube, red, blue, g, a, b, h, c, d }
}

fn sorted(mut v: Vec<NodeId>) -> Vec<NodeId> {
    v.sort();
    v
}

#[test]
fn a_new_scene_reports_every_drawn_node_as_added() {
    let f = fixture();
    let ch = f.s.changes();
    assert_eq!((ch.from, ch.to, f.s.revision()), (0, 1, 1));
    assert_eq!(ch.added, vec![f.a, f.b, f.c, f.d], "in propagation order, groups left out");
    assert!(ch.moved.is_empty() && ch.removed.is_empty() && ch.restyled.is_empty());
    assert!(ch.order_changed);
    assert!(!f.s.needs_update());
}

#[test]
fn moving_a_parent_moves_exactly_its_drawn_descendants() {
    let mut f = fixture();
    f.s.set_local_transform(f.g, Transform::from_translation(Vec3::X)).unwrap();
    assert!(f.s.needs_update());
    assert_eq!(f.s.update_transforms(), 5, "g, a, b, h, c");
    let ch = f.s.changes();
    assert_eq!((ch.from, ch.to), (1, 2));
    assert_eq!(sorted(ch.moved.clone()), sorted(vec![f.a, f.b, f.c]));
    assert!(ch.added.is_empty() && ch.removed.is_empty() && ch.restyled.is_empty() && !ch.order_changed);
    // The instance carries the new matrix.
    let inst = f.s.instance(f.c).unwrap();
    assert_eq!(inst.world_from_local.translation, Vec3::X.into());
    assert!(f.s.instance(f.h).is_none(), "a group is not an instance");
    // Setting the same transform again is an update that moves nothing.
    f.s.set_local_transform(f.g, Transform::from_translation(Vec3::X)).unwrap();
    f.s.update_transforms();
    assert_eq!(f.s.revision(), 3);
    assert!(f.s.changes().is_empty(), "{:?}", f.s.changes());
}

#[test]
fn adding_and_removing_drawn_nodes_changes_the_order() {
    let mut f = fixture();
    let e = f.s.add_node(Some(f.h), NodeDesc::new("e").mesh(f.cube)).unwrap();
    let group = f.s.add_node(Some(f.h), NodeDesc::new("empty group")).unwrap();
    assert!(f.s.needs_update());
    f.s.update_transforms();
    let ch = f.s.changes();
    assert_eq!(ch.added, vec![e]);
    assert!(ch.order_changed && ch.moved.is_empty() && ch.removed.is_empty());
    // d's triangles now start after e's.
    assert_eq!(f.s.instance(f.d).unwrap().first_triangle, 48);

    // Removing a group that draws nothing changes nothing drawn, but still needs an update.
    let rev = f.s.revision();
    f.s.remove_node(group).unwrap();
    assert!(f.s.needs_update(), "a removal is an edit");
    assert_eq!(f.s.update_transforms(), 0);
    assert_eq!(f.s.revision(), rev + 1);
    assert!(f.s.changes().is_empty());

    // Removing h reports its drawn descendants, whose handles are stale now.
    let removed = f.s.remove_node(f.h).unwrap();
    assert_eq!(removed.nodes, 3);
    f.s.update_transforms();
    let ch = f.s.changes();
    assert_eq!(sorted(ch.removed.clone()), sorted(vec![f.c, e]));
    assert!(ch.order_changed && ch.added.is_empty());
    assert!(f.s.instance(f.c).is_none());
    assert_eq!(f.s.instance(f.d).unwrap().first_triangle, 24);
    assert!(matches!(f.s.set_local_transform(f.c, Transform::IDENTITY), Err(Error::StaleNode(_))));
}

#[test]
fn a_node_added_and_removed_between_updates_is_never_reported() {
    let mut f = fixture();
    let e = f.s.add_node(None, NodeDesc::new("e").mesh(f.cube)).unwrap();
    f.s.remove_node(e).unwrap();
    f.s.update_transforms();
    assert!(f.s.changes().is_empty(), "{:?}", f.s.changes());
}

#[test]
fn reparenting_changes_order_position_and_inherited_material() {
    let mut f = fixture();
    f.s.set_local_transform(f.d, Transform::from_translation(Vec3::Y)).unwrap();
    f.s.update_transforms();
    // c (red, under h) moves under d, which has no material and sits at y = 1.
    f.s.set_parent(f.c, Some(f.d), Keep::Local).unwrap();
    assert!(f.s.needs_update());
    f.s.update_transforms();
    let ch = f.s.changes();
    assert!(ch.order_changed);
    assert_eq!(ch.moved, vec![f.c]);
    assert_eq!(ch.restyled, vec![f.c]);
    assert!(ch.added.is_empty() && ch.removed.is_empty());
    let inst = f.s.instance(f.c).unwrap();
    assert_eq!(inst.material, None);
    assert_eq!(inst.first_triangle, 36, "after a, b and d");
    // Keep::World under a parent that does not move it: order only.
    f.s.set_parent(f.c, Some(f.g), Keep::World).unwrap();
    f.s.update_transforms();
    let ch = f.s.changes();
    assert!(ch.order_changed && ch.moved.is_empty());
    assert_eq!(ch.restyled, vec![f.c], "red again");
}

#[test]
fn set_mesh_reports_added_removed_and_swaps() {
    let mut f = fixture();
    let tri = f.s.add_mesh(Mesh::new("tri", vec![Vec3::ZERO, Vec3::X, Vec3::Y], None, None, vec![0, 1, 2]).unwrap());
    let other_cube = f.s.add_mesh(shapes::cube("cube 2").unwrap());
    // A group gets a mesh: added.
    f.s.set_mesh(f.h, Some(tri)).unwrap();
    assert!(f.s.needs_update());
    f.s.update_transforms();
    assert_eq!(f.s.changes().added, vec![f.h]);
    assert!(f.s.changes().order_changed);
    // A swap for a mesh of the same triangle count: removed + added, order kept.
    f.s.set_mesh(f.a, Some(other_cube)).unwrap();
    f.s.update_transforms();
    let ch = f.s.changes();
    assert_eq!((ch.removed.clone(), ch.added.clone()), (vec![f.a], vec![f.a]));
    assert!(!ch.order_changed);
    assert_eq!(f.s.instance(f.a).unwrap().mesh, other_cube);
    // A swap for a mesh of another count shifts the triangles after it.
    f.s.set_mesh(f.a, Some(tri)).unwrap();
    f.s.update_transforms();
    assert!(f.s.changes().order_changed);
    assert_eq!(f.s.instance(f.b).unwrap().first_triangle, 1);
    // Cleared: removed. Cleared and set back before the update: nothing.
    f.s.set_mesh(f.a, None).unwrap();
    f.s.update_transforms();
    assert_eq!(f.s.changes().removed, vec![f.a]);
    f.s.set_mesh(f.b, None).unwrap();
    f.s.set_mesh(f.b, Some(f.cube)).unwrap();
    f.s.update_transforms();
    assert!(f.s.changes().is_empty());
}

#[test]
fn material_changes_restyle_the_nodes_that_inherit_them() {
    let mut f = fixture();
    let green = f.s.add_material(Material::color("green", [0.0, 1.0, 0.0]));
    f.s.set_material(f.g, Some(green)).unwrap();
    assert!(f.s.needs_update(), "the inherited material is propagated");
    f.s.update_transforms();
    let ch = f.s.changes();
    assert_eq!(sorted(ch.restyled.clone()), sorted(vec![f.a, f.c]), "b keeps its own blue");
    assert!(ch.moved.is_empty() && !ch.order_changed);
    assert_eq!(f.s.instance(f.c).unwrap().material, Some(green));
    f.s.set_material(f.b, None).unwrap();
    f.s.update_transforms();
    assert_eq!(f.s.changes().restyled, vec![f.b]);
    assert_eq!(f.s.instance(f.b).unwrap().material, Some(green));
    let _ = (f.red, f.blue);
}

#[test]
fn the_revision_protocol() {
    let mut f = fixture();
    let synced = f.s.stamp();
    assert!(matches!(f.s.delta_since(synced), SceneDelta::UpToDate));
    // Nothing to do: no new revision, the last report stays readable.
    assert_eq!(f.s.update_transforms(), 0);
    assert_eq!(f.s.stamp(), synced);
    assert_eq!(f.s.changes().to, synced.revision);
    // One update behind: apply.
    f.s.set_local_transform(f.d, Transform::from_rotation(Quat::from_rotation_y(0.3))).unwrap();
    f.s.update_transforms();
    match f.s.delta_since(synced) {
        SceneDelta::Apply(ch) => assert_eq!((ch.from, ch.moved.clone()), (synced.revision, vec![f.d])),
        other => panic!("expected Apply, got {other:?}"),
    }
    // Two updates behind: rebuild.
    f.s.set_local_transform(f.d, Transform::IDENTITY).unwrap();
    f.s.update_transforms();
    assert!(matches!(f.s.delta_since(synced), SceneDelta::Rebuild));
    // A clone is another scene, with another id.
    let copy = f.s.clone();
    assert_ne!(copy.id(), f.s.id());
    assert_eq!(copy.revision(), f.s.revision());
    assert!(matches!(copy.delta_since(f.s.stamp()), SceneDelta::Rebuild));
    assert!(matches!(f.s.delta_since(f.s.stamp()), SceneDelta::UpToDate));
    assert_ne!(Scene::new().id(), Scene::new().id());
}

#[test]
fn removing_a_node_removes_the_cameras_on_its_subtree() {
    let mut f = fixture();
    let projection = Projection::perspective(Angle::degrees(50.0), 1.0, 0.1, 100.0).unwrap();
    for (name, node) in [("on c", f.c), ("on d", f.d)] {
        f.s.cameras.push(SceneCamera { name: name.into(), node, projection });
    }
    let removed = f.s.remove_node(f.h).unwrap();
    assert_eq!(removed.cameras.len(), 1);
    assert_eq!(removed.cameras[0].name, "on c");
    assert_eq!(f.s.cameras.len(), 1);
    assert_eq!(f.s.cameras[0].node, f.d);
    assert!(f.s.cameras.iter().all(|c| f.s.node(c.node).is_some()));
}

#[test]
fn instance_lookup_agrees_with_the_flattened_list() {
    let mut f = fixture();
    for inst in f.s.instances() {
        assert_eq!(f.s.instance(inst.node), Some(inst));
    }
    assert_eq!(f.s.instance_count(), 4);
    f.s.remove_node(f.a).unwrap();
    f.s.update_transforms();
    let list = f.s.instances();
    assert_eq!(list.len(), 3);
    for inst in list {
        assert_eq!(f.s.instance(inst.node), Some(inst));
    }
}

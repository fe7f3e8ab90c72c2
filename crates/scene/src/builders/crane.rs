//! Tower cranes for the traffic city: a nested hierarchy that changes every frame.
//!
//! ```text
//! crane (group at a block's center)
//! └─ mast      a lattice-less box column, height H
//!    └─ jib     at the mast top, turns about y      (rotation LINEAR, one turn per period)
//!       └─ trolley  slides along the jib (+x)        (translation LINEAR, out and back)
//!          ├─ cable  hangs from the trolley           (scale CUBICSPLINE: its length)
//!          └─ hook   moves up and down                (translation CUBICSPLINE, zero tangents:
//!                                                      eases in and out at each end)
//! ```
//!
//! Each part is animated relative to its parent, so the hook's world motion is the
//! composition of all four. The cable's length and the hook's depth use the same keys and
//! the same (zero) tangents, so the cable always ends at the hook. Every curve of a crane
//! has the same period, its animation loops ([`Wrap::Loop`]).
//!
//! The mast stands where the four lots of a block meet: buildings keep at least 1 unit from
//! their lot's edges, so a 1.6-wide mast there touches none. The jib turns above the tallest
//! building within its reach plus a clearance, so neither jib nor hook passes through one.

use glam::{Quat, Vec3};

use crate::animation::{Animation, Curve, Interpolation, Sampler, Wrap};
use crate::rng::Rng;
use crate::shapes::MeshBuilder;
use crate::{Material, MeshId, NodeDesc, NodeId, Result, Scene, Transform};

/// Jib length in front of the mast (the trolley's reach).
pub(super) const JIB_REACH: f32 = 40.0;
/// Counter-jib length behind the mast.
const COUNTER_JIB: f32 = 12.0;
/// Height of the jib above the tallest building within reach.
const CLEARANCE: f32 = 20.0;
/// Seconds for one turn of the jib (and one cycle of trolley and hook).
pub(super) const PERIOD: f32 = 48.0;
/// The hook's depth below the jib: shallowest and deepest.
const HOOK_DEPTH: [f32; 2] = [4.0, 16.0];
/// The hook block's height.
const HOOK_HEIGHT: f32 = 1.5;

/// The meshes every crane shares.
pub(super) struct CraneMeshes {
    jib: MeshId,
    trolley: MeshId,
    cable: MeshId,
    hook: MeshId,
    paint: crate::MaterialId,
}

impl CraneMeshes {
    /// Adds the crane meshes (all but the mast, whose height differs per crane) and the crane
    /// paint to the scene.
    pub(super) fn add(scene: &mut Scene) -> Result<Self> {
        let one = |scene: &mut Scene, name: &str, min: Vec3, max: Vec3, cells: [u32; 3]| {
            let mut b = MeshBuilder::default();
            b.add_box(min, max, cells, true);
            b.build(name).map(|m| scene.add_mesh(m))
        };
        let mut jib = MeshBuilder::default();
        jib.add_box(Vec3::new(-COUNTER_JIB, 0.0, -0.6), Vec3::new(JIB_REACH, 1.5, 0.6), [13, 1, 1], true);
        jib.add_box(Vec3::new(-COUNTER_JIB, -2.0, -1.2), Vec3::new(-COUNTER_JIB + 4.0, 0.0, 1.2), [1, 1, 1], true);
        jib.add_box(Vec3::new(-1.0, 1.5, -1.0), Vec3::new(1.0, 4.5, 1.0), [1, 1, 1], false);
        let jib = scene.add_mesh(jib.build("crane jib")?);
        let trolley = one(scene, "crane trolley", Vec3::new(-1.0, -0.8, -0.8), Vec3::new(1.0, 0.0, 0.8), [1, 1, 1])?;
        let cable = one(scene, "crane cable", Vec3::new(-0.06, -1.0, -0.06), Vec3::new(0.06, 0.0, 0.06), [1, 1, 1])?;
        let hook = one(scene, "crane hook", Vec3::new(-0.6, -HOOK_HEIGHT, -0.6), Vec3::new(0.6, 0.0, 0.6), [1, 1, 1])?;
        let paint = scene.add_material(Material::color("crane paint", [0.95, 0.75, 0.10]));
        Ok(Self { jib, trolley, cable, hook, paint })
    }
}

/// Keys at every quarter period, with the values of `f(k)` for k = 0..=4.
fn quarters<T: crate::animation::Keyframe>(f: impl Fn(usize) -> T) -> (Vec<f32>, Vec<T>) {
    ((0..=4).map(|k| k as f32 * PERIOD / 4.0).collect(), (0..=4).map(f).collect())
}

/// A CUBICSPLINE sampler through `values` at the quarter keys with zero tangents.
fn eased(values: impl Fn(usize) -> Vec3) -> Result<Sampler<Vec3>> {
    let (times, v) = quarters(values);
    let keys = v.into_iter().flat_map(|x| [Vec3::ZERO, x, Vec3::ZERO]).collect();
    Sampler::new(times, keys, Interpolation::CubicSpline).map_err(crate::Error::InvalidParams)
}

/// Adds one crane under `parent` at `base` (world, on the ground), its jib `height` above the
/// ground, and its looping animation to the scene's animations. Returns the crane's group node.
pub(super) fn add_crane(
    scene: &mut Scene,
    meshes: &CraneMeshes,
    parent: NodeId,
    index: usize,
    base: Vec3,
    height: f32,
    rng: &mut Rng,
) -> Result<NodeId> {
    let bad = crate::Error::InvalidParams;
    let phase = rng.f32() * std::f32::consts::TAU;
    let turn = |k: usize| Quat::from_rotation_y(phase + k as f32 * std::f32::consts::FRAC_PI_2);
    let (times, turns) = quarters(turn);
    let jib_curve = Sampler::new(times, turns, Interpolation::Linear).map_err(bad)?;
    let reach = [8.0, JIB_REACH - 4.0];
    let trolley_curve = Sampler::new(
        vec![0.0, PERIOD / 2.0, PERIOD],
        vec![Vec3::X * reach[0], Vec3::X * reach[1], Vec3::X * reach[0]],
        Interpolation::Linear,
    )
    .map_err(bad)?;
    let depth = |k: usize| HOOK_DEPTH[k % 2];
    let hook_curve = eased(|k| Vec3::NEG_Y * depth(k))?;
    let cable_curve = eased(|k| Vec3::new(1.0, depth(k), 1.0))?;

    let name = |part: &str| format!("crane {index} {part}");
    let group = scene.add_node(
        Some(parent),
        NodeDesc::new(format!("crane {index}")).transform(Transform::from_translation(base)).material(meshes.paint),
    )?;
    let mut column = MeshBuilder::default();
    let sections = ((height / 6.0).round() as u32).max(1);
    column.add_box(Vec3::new(-0.8, 0.0, -0.8), Vec3::new(0.8, height, 0.8), [1, sections, 1], false);
    let mast_mesh = scene.add_mesh(column.build(&name("mast"))?);
    let mast = scene.add_node(Some(group), NodeDesc::new(name("mast")).mesh(mast_mesh))?;
    let start = |s: &Sampler<Vec3>| s.sample(0.0);
    let jib = scene.add_node(
        Some(mast),
        NodeDesc::new(name("jib"))
            .transform(Transform::from_translation(Vec3::Y * height).with_rotation(jib_curve.sample(0.0)))
            .mesh(meshes.jib),
    )?;
    let trolley = scene.add_node(
        Some(jib),
        NodeDesc::new(name("trolley"))
            .transform(Transform::from_translation(start(&trolley_curve)))
            .mesh(meshes.trolley),
    )?;
    let cable = scene.add_node(
        Some(trolley),
        NodeDesc::new(name("cable")).transform(Transform::from_scale(start(&cable_curve))).mesh(meshes.cable),
    )?;
    let hook = scene.add_node(
        Some(trolley),
        NodeDesc::new(name("hook")).transform(Transform::from_translation(start(&hook_curve))).mesh(meshes.hook),
    )?;
    scene.add_animation(
        Animation::new(format!("crane {index}"))
            .with_wrap(Wrap::Loop)
            .with_channel(jib, Curve::Rotation(jib_curve))
            .with_channel(trolley, Curve::Translation(trolley_curve))
            .with_channel(cable, Curve::Scale(cable_curve))
            .with_channel(hook, Curve::Translation(hook_curve)),
    );
    Ok(group)
}

/// The jib height for a crane whose reach covers buildings up to `tallest`.
pub(super) fn jib_height(tallest: f32) -> f32 {
    tallest + CLEARANCE
}

/// How far from the mast a crane's parts reach (for finding the buildings below it).
pub(super) const REACH: f32 = JIB_REACH + 2.0;

// The hook's lowest point stays above the tallest building within reach, and the
// counter-jib swings inside the reach searched for buildings.
const _: () = assert!(CLEARANCE - HOOK_DEPTH[1] - HOOK_HEIGHT > 1.0 && COUNTER_JIB < REACH);

//! # sightline-scene
//!
//! The scene side of sightline: a node hierarchy with local and world transforms, meshes
//! shared by many nodes (instancing), materials inherited down the tree, cameras with
//! perspective, orthographic, oblique and axonometric projections, loaders for glTF and OBJ,
//! and builders that make scenes of 10^6–10^7 triangles in code.
//!
//! Conventions (shared with the other crates): right-handed world, +y up; column vectors;
//! matrices named for the way they map (`world_from_local`, `clip_from_world`); view space
//! looks down −z; OpenGL clip space.
//!
//! ```
//! use sightline_scene::*;
//! use glam::Vec3;
//!
//! let mut scene = Scene::new();
//! let cube = scene.add_mesh(shapes::cube("cube")?);
//! let group = scene.add_node(None, NodeDesc::new("group").transform(Transform::from_translation(Vec3::X)))?;
//! for i in 0..3 {
//!     let t = Transform::from_translation(Vec3::new(0.0, 0.0, 2.0 * i as f32));
//!     scene.add_node(Some(group), NodeDesc::new(format!("cube {i}")).transform(t).mesh(cube))?;
//! }
//! scene.update_transforms();
//! let stats = scene.stats();
//! assert_eq!((stats.instances, stats.triangles, stats.unique_triangles), (3, 36, 12));
//! # Ok::<(), sightline_scene::Error>(())
//! ```

#![forbid(unsafe_code)]
#![warn(missing_docs)]
// `!(x > 0.0)` is how this code says "not positive, or NaN": the negated comparison is the point.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod angle;
pub mod animation;
pub mod assets;
mod bounds;
pub mod builders;
mod camera;
mod error;
pub mod export;
#[doc(hidden)]
pub mod fuzzing;
pub mod gltf_loader;
mod graph;
mod material;
mod mesh;
pub mod obj_loader;
pub mod path;
mod projection;
pub mod rng;
pub mod shapes;
mod stats;
mod transform;
pub mod views;

pub use angle::Angle;
pub use animation::Animation;
pub use assets::LoadOptions;
pub use bounds::Aabb;
pub use camera::{projection_onto_plane, Camera, LookAt, View};
pub use error::{Error, Result};
pub use graph::{
    Changes, Instance, Keep, MaterialId, MeshId, Node, NodeDesc, NodeId, Prefab, Removed, Scene, SceneCamera,
    SceneDelta, SceneId, SceneStamp, MAX_DRAWN_TRIANGLES,
};
pub use material::{AlphaMode, Material, Texture, DEFAULT_ALPHA_CUTOFF};
pub use mesh::{Face, Mesh};
pub use projection::Projection;
pub use stats::SceneStats;
pub use transform::{affine_from_mat4, validate_affine, Transform};

/// Loads a scene from a `.gltf`, `.glb` or `.obj` file, chosen by extension, with world
/// transforms already propagated. Files it refers to must be inside its folder (see
/// [`assets`]; [`load_with`] allows other folders).
pub fn load(path: impl AsRef<std::path::Path>) -> Result<Scene> {
    load_with(path, &LoadOptions::default())
}

/// [`load`] with options: other folders referenced files may come from, a cap on the bytes
/// read.
pub fn load_with(path: impl AsRef<std::path::Path>, options: &LoadOptions) -> Result<Scene> {
    let path = path.as_ref();
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let mut scene = match ext.as_deref() {
        Some("gltf") | Some("glb") => gltf_loader::load_gltf_with(path, options)?,
        Some("obj") => obj_loader::load_obj_with(path, options)?,
        _ => return Err(Error::load(path, "unknown file type: expected .gltf, .glb or .obj")),
    };
    scene.update_transforms();
    Ok(scene)
}

/// Loads a file (as [`load_with`]) into `scene` as a [`Prefab`] named after the file: its
/// meshes and materials are added once, its warnings appended to `scene.warnings`; place it
/// with [`Scene::instantiate_prefab`] as many times as needed.
///
/// ```no_run
/// use glam::Vec3;
/// use sightline_scene::*;
/// let mut scene = Scene::new();
/// let tree = load_prefab(&mut scene, "tree.glb", &LoadOptions::default())?;
/// let forest = scene.add_node(None, NodeDesc::new("forest"))?;
/// for i in 0..1000 {
///     let at = Transform::from_translation(Vec3::new((i % 40) as f32 * 5.0, 0.0, (i / 40) as f32 * 5.0));
///     scene.instantiate_prefab(&tree, Some(forest), at)?;
/// }
/// scene.update_transforms();
/// # Ok::<(), sightline_scene::Error>(())
/// ```
pub fn load_prefab(scene: &mut Scene, path: impl AsRef<std::path::Path>, options: &LoadOptions) -> Result<Prefab> {
    let path = path.as_ref();
    let loaded = load_with(path, options)?;
    let name = path.file_name().map_or_else(|| "model".into(), |n| n.to_string_lossy().into_owned());
    Ok(scene.add_prefab_owned(loaded).with_name(name))
}

/// Loads a file (as [`load_with`]) and places it once in `scene` under `parent` (`None`: as
/// a root): a new node named after the file holds the file's nodes; the file's meshes,
/// materials, cameras and warnings join the scene. Returns the new node. Call
/// [`Scene::update_transforms`] before drawing.
pub fn load_into(
    scene: &mut Scene,
    path: impl AsRef<std::path::Path>,
    parent: Option<NodeId>,
    options: &LoadOptions,
) -> Result<NodeId> {
    if let Some(p) = parent {
        scene.try_node(p)?;
    }
    let prefab = load_prefab(scene, path, options)?;
    scene.instantiate_prefab(&prefab, parent, Transform::IDENTITY)
}

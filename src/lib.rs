//! # sightline
//!
//! A scene-graph engine with spatial data structures that decides what is visible in large
//! 3D scenes and draws it on the CPU. This facade re-exports the three crates:
//!
//! * [`scene`] (sightline-scene): nodes, transforms, meshes, materials, cameras, loaders,
//!   builders;
//! * [`spatial`] (sightline-spatial): bounding volumes, frusta, BVHs, octrees, BSP trees;
//! * [`render`] (sightline-render): the rasterizer with z-buffer and hierarchical z-buffer,
//!   and the ray caster.
//!
//! `use sightline::prelude::*;` brings the everyday types into scope. [`SceneSpec`] parses
//! the `--scene` argument of the command-line program (`city`, `city:TRIS`, `boxfield` or a
//! file). [`hud`] burns a few lines of text (a frame's readout) into an image.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

use std::path::PathBuf;

pub mod boxfield;
pub mod hud;

pub use sightline_render as render;
pub use sightline_scene as scene;
pub use sightline_spatial as spatial;

/// The everyday types.
pub mod prelude {
    pub use glam::{Affine3A, Mat4, Quat, Vec2, Vec3};
    pub use sightline_render::Framebuffer;
    pub use sightline_scene::builders::{boxfield, city, BoxfieldParams, CityParams};
    pub use sightline_scene::path::CameraKey;
    pub use sightline_scene::{
        Aabb, Camera, Instance, Keep, Material, Mesh, MeshId, NodeDesc, NodeId, Projection, Scene, Transform, View,
    };
}

/// Triangles of the default city.
pub const DEFAULT_CITY_TRIANGLES: u64 = 1_000_000;

/// A scene named on the command line.
#[derive(Debug, Clone, PartialEq)]
pub enum SceneSpec {
    /// The procedural city with at least this many triangles.
    City(u64),
    /// The occlusion benchmark's field of boxes.
    Boxfield,
    /// A `.gltf`, `.glb` or `.obj` file.
    File(PathBuf),
}

impl Default for SceneSpec {
    fn default() -> Self {
        SceneSpec::City(DEFAULT_CITY_TRIANGLES)
    }
}

impl std::str::FromStr for SceneSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "city" => Ok(SceneSpec::City(DEFAULT_CITY_TRIANGLES)),
            "boxfield" => Ok(SceneSpec::Boxfield),
            _ => {
                if let Some(n) = s.strip_prefix("city:") {
                    let n: u64 = n
                        .replace('_', "")
                        .parse()
                        .map_err(|_| format!("'{s}': expected city:TRIANGLES, e.g. city:10000000"))?;
                    if !(1_000..=100_000_000).contains(&n) {
                        return Err(format!("'{s}': the city's triangle count must be between 1000 and 100000000"));
                    }
                    Ok(SceneSpec::City(n))
                } else {
                    Ok(SceneSpec::File(PathBuf::from(s)))
                }
            }
        }
    }
}

/// A scene ready to draw, with the street layout when it is a built-in city.
#[derive(Debug, Clone)]
pub struct LoadedScene {
    /// The scene, world transforms propagated.
    pub scene: scene::Scene,
    /// The city's street grid (built-in cities only).
    pub layout: Option<scene::builders::CityLayout>,
}

impl SceneSpec {
    /// Builds or loads the scene; a file may refer only to files inside its own folder.
    pub fn load(&self) -> Result<LoadedScene, scene::Error> {
        self.load_with(&scene::LoadOptions::default())
    }

    /// Builds or loads the scene; `options` apply to a file (other folders its buffers,
    /// images and material libraries may come from, a cap on the bytes read).
    pub fn load_with(&self, options: &scene::LoadOptions) -> Result<LoadedScene, scene::Error> {
        match self {
            SceneSpec::City(n) => {
                let c = scene::builders::city(&scene::builders::CityParams::for_triangles(*n))?;
                Ok(LoadedScene { scene: c.scene, layout: Some(c.layout) })
            }
            SceneSpec::Boxfield => {
                Ok(LoadedScene { scene: scene::builders::boxfield(&Default::default())?, layout: None })
            }
            SceneSpec::File(p) => Ok(LoadedScene { scene: scene::load_with(p, options)?, layout: None }),
        }
    }
}

impl LoadedScene {
    /// The camera path of the given kind (`street` or `aerial`) with `frames` keys.
    pub fn path(&self, street: bool, frames: usize) -> Result<Vec<scene::path::CameraKey>, scene::Error> {
        match &self.layout {
            Some(l) if street => Ok(l.street_path(frames, 11)),
            Some(l) => Ok(l.aerial_path(frames)),
            None => scene::path::generic_path(&self.scene.world_aabb(), street, frames),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_specs_parse() {
        assert_eq!("city".parse::<SceneSpec>().unwrap(), SceneSpec::City(1_000_000));
        assert_eq!("city:10000000".parse::<SceneSpec>().unwrap(), SceneSpec::City(10_000_000));
        assert_eq!("boxfield".parse::<SceneSpec>().unwrap(), SceneSpec::Boxfield);
        assert_eq!("a.obj".parse::<SceneSpec>().unwrap(), SceneSpec::File("a.obj".into()));
        assert!("city:abc".parse::<SceneSpec>().is_err());
        assert!("city:5".parse::<SceneSpec>().is_err());
    }
}

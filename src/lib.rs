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
//! the `--scene` argument of the command-line program (`city`, `city:TRIS`, `city+traffic:N`,
//! `boxfield` or a file). [`hud`] burns a few lines of text (a frame's readout) into an image;
//! [`gif_out`] writes a walk as an animated GIF.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

use std::path::PathBuf;

pub mod args;
pub mod boxfield;
pub mod gif_out;
pub mod hud;

pub use sightline_render as render;
pub use sightline_scene as scene;
pub use sightline_spatial as spatial;

/// The everyday types, and the few functions a program building a scene in code calls: the
/// builders (`city`, `boxfield`, `scatter`), meshes made in code (`shapes`), loading a file
/// once to place it many times (`load_prefab`), and writing a frame as PNG
/// (`write_color_png`). `examples/city_builder.rs` uses nothing else.
pub mod prelude {
    pub use glam::{Affine3A, Mat4, Quat, Vec2, Vec3};
    pub use sightline_render::output::write_color_png;
    pub use sightline_render::{aa, Framebuffer, Method, RenderOptions, ShadeOptions, Sky, Visibility, World};
    pub use sightline_scene::builders::{boxfield, city, scatter, BoxfieldParams, CityParams, ScatterParams};
    pub use sightline_scene::path::CameraKey;
    pub use sightline_scene::shapes;
    pub use sightline_scene::{
        load_into, load_prefab, Aabb, Angle, Camera, Instance, Keep, LoadOptions, LookAt, Material, Mesh, MeshId,
        NodeDesc, NodeId, Prefab, Projection, Scene, Transform, View,
    };
}

/// Triangles of the default city.
pub const DEFAULT_CITY_TRIANGLES: u64 = 1_000_000;

/// A scene named on the command line.
#[derive(Debug, Clone, PartialEq)]
pub enum SceneSpec {
    /// The procedural city with at least this many triangles.
    City(u64),
    /// The default city with this many vehicles driving its streets and tower cranes, all
    /// moved by the scene's animations (`scene.animate(t)`; a walk's frame f is t = f / 30 s).
    CityTraffic(u32),
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
                if let Some(n) = s.strip_prefix("city+traffic:") {
                    let n: u32 = n
                        .replace('_', "")
                        .parse()
                        .map_err(|_| format!("'{s}': expected city+traffic:VEHICLES, e.g. city+traffic:1000"))?;
                    if n > scene::builders::MAX_VEHICLES {
                        return Err(format!(
                            "'{s}': the number of vehicles must be at most {}",
                            scene::builders::MAX_VEHICLES
                        ));
                    }
                    Ok(SceneSpec::CityTraffic(n))
                } else if let Some(n) = s.strip_prefix("city:") {
                    let n: u64 = n
                        .replace('_', "")
                        .parse()
                        .map_err(|_| format!("'{s}': expected city:TRIANGLES, e.g. city:10000000"))?;
                    if !(1_000..=1_000_000_000).contains(&n) {
                        return Err(format!("'{s}': the city's triangle count must be between 1000 and 1000000000"));
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
            SceneSpec::CityTraffic(n) => {
                let c = scene::builders::city_with_traffic(&scene::builders::TrafficParams::new(*n))?;
                Ok(LoadedScene { scene: c.scene, layout: Some(c.layout) })
            }
            SceneSpec::Boxfield => {
                Ok(LoadedScene { scene: scene::builders::boxfield(&Default::default())?, layout: None })
            }
            SceneSpec::File(p) => Ok(LoadedScene { scene: scene::load_with(p, options)?, layout: None }),
        }
    }
}

/// The street walk through a built-in city with `frames` keys: the path `walk`, `bench` and
/// `path --kind street` use, and where the viewer starts.
pub fn street_walk(layout: &scene::builders::CityLayout, frames: usize) -> Vec<scene::path::CameraKey> {
    // The seed that chooses the turns at the intersections.
    layout.street_path(frames, 11)
}

impl LoadedScene {
    /// The camera path of the given kind (`street` or `aerial`) with `frames` keys.
    pub fn path(&self, street: bool, frames: usize) -> Result<Vec<scene::path::CameraKey>, scene::Error> {
        match &self.layout {
            Some(l) if street => Ok(street_walk(l, frames)),
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
        assert_eq!("city:1_000_000_000".parse::<SceneSpec>().unwrap(), SceneSpec::City(1_000_000_000));
        assert!("city:1000000001".parse::<SceneSpec>().unwrap_err().contains("1000000000"));
        assert_eq!("city+traffic:1000".parse::<SceneSpec>().unwrap(), SceneSpec::CityTraffic(1000));
        assert_eq!("city+traffic:10_000".parse::<SceneSpec>().unwrap(), SceneSpec::CityTraffic(10_000));
        assert!("city+traffic:".parse::<SceneSpec>().is_err());
        assert!("city+traffic:-3".parse::<SceneSpec>().is_err());
        assert!("city+traffic:2000000".parse::<SceneSpec>().is_err());
    }

    #[test]
    fn traffic_city_builds_and_moves() {
        let mut s = "city+traffic:20".parse::<SceneSpec>().unwrap().load().unwrap();
        assert!(s.layout.is_some(), "the street path needs the layout");
        let plain = SceneSpec::City(DEFAULT_CITY_TRIANGLES).load().unwrap().scene.stats();
        let stats = s.scene.stats();
        assert!(stats.instances > plain.instances + 20, "vehicles and cranes are drawn");
        // 20 vehicle animations and at least one crane.
        assert!(s.scene.animations().len() > 20);
        let before = s.scene.instances();
        s.scene.animate(1.0 / 30.0).unwrap();
        s.scene.update_transforms();
        let moved =
            s.scene.instances().iter().zip(&before).filter(|(a, b)| a.world_from_local != b.world_from_local).count();
        assert!(moved >= 20 + 4, "{moved} instances moved in one frame");
    }
}

/// The README's library example, compiled and run as a doctest.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

//! The one object a program holds: a scene, the structures that decide what is visible in
//! it, and the state carried from frame to frame.
//!
//! A program is: build or load a scene, change it, and [`World::render`] each frame with a
//! chosen visibility method. Edits go through [`World::scene_mut`] (or [`World::animate`]);
//! the next frame propagates them and brings the culler and the ray caster up to date (moved
//! instances are refitted, added or removed ones rebuild what they must), so a frame is never
//! drawn from a stale scene and nothing has to be rebuilt by hand. Each structure is built on
//! first use: a program that only rasterizes never builds the ray caster's BVHs.
//!
//! ```
//! use glam::Vec3;
//! use sightline_render::{Framebuffer, Method, RenderOptions, Visibility, World};
//! use sightline_scene::{shapes, Angle, Camera, LookAt, NodeDesc, Scene, Transform};
//!
//! let mut scene = Scene::new();
//! let cube = scene.add_mesh(shapes::cube("cube")?);
//! let node = scene.add_node(None, NodeDesc::new("cube").mesh(cube))?;
//! let mut world = World::new(scene);
//! let look = LookAt { eye: Vec3::new(2.0, 1.5, 3.0), fovy: Angle::degrees(50.0), far: 100.0, ..LookAt::default() };
//! let camera = Camera::perspective(&look, 1.0)?;
//! let mut fb = Framebuffer::new(64, 64)?;
//! world.render(&camera, Method::Hzb, &mut fb, &RenderOptions::default())?;
//! // Move the cube: the next frame sees it moved, whatever the method.
//! world.scene_mut().set_local_transform(node, Transform::from_translation(Vec3::X))?;
//! let report = world.render(&camera, Visibility::RayCast, &mut fb, &RenderOptions::default())?;
//! assert!(report.ms_total >= 0.0 && fb.ids.iter().any(|&id| id != 0));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::path::Path;

use rayon::prelude::*;
use serde::Serialize;
use sightline_scene::{Camera, Mesh, MeshId, Scene};
use slotmap::SecondaryMap;

use crate::awake::with_helper_awake;
use crate::{CullStats, Culler, FrameStats, Framebuffer, Method, RayCaster, RaycastOptions, RaycastStats};
use crate::{RenderOptions, Result};

/// How a frame decides visibility: a rasterizing culling method, or ray casting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Visibility {
    /// Rasterization with a culling method (brute force included).
    Cull(Method),
    /// One primary ray per pixel through the two-level BVH.
    RayCast,
}

impl From<Method> for Visibility {
    fn from(m: Method) -> Self {
        Visibility::Cull(m)
    }
}

impl Visibility {
    /// Every method: the culling methods, then ray casting.
    pub fn all() -> Vec<Visibility> {
        Method::ALL.iter().map(|&m| Visibility::Cull(m)).chain([Visibility::RayCast]).collect()
    }

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Visibility::Cull(m) => m.name(),
            Visibility::RayCast => "raycast",
        }
    }
}

/// What one frame did.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FrameReport {
    /// Wall time of the frame, milliseconds, bringing the structures up to date included.
    pub ms_total: f64,
    /// Culling counters (rasterizing methods).
    pub cull: Option<CullStats>,
    /// Rasterizer counters (rasterizing methods).
    pub raster: Option<FrameStats>,
    /// Ray counts (ray casting).
    pub rays: Option<RaycastStats>,
}

/// A scene with its culler and ray caster (see the module docs).
#[derive(Debug)]
pub struct World {
    scene: Scene,
    culler: Option<Culler>,
    caster: Option<RayCaster>,
}

impl World {
    /// A world around `scene` (edits still pending are propagated by the first frame).
    pub fn new(scene: Scene) -> World {
        World { scene, culler: None, caster: None }
    }

    /// Loads a glTF, GLB or OBJ file (see `sightline_scene::load`).
    pub fn load(path: impl AsRef<Path>) -> Result<World> {
        Ok(World::new(sightline_scene::load(path)?))
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The scene, to edit: move, add, remove, reparent, instantiate. The next frame follows;
    /// a scene put in place of this one (`*world.scene_mut() = other`) gets its culler and
    /// ray caster built anew.
    pub fn scene_mut(&mut self) -> &mut Scene {
        &mut self.scene
    }

    /// Gives the scene back.
    pub fn into_scene(self) -> Scene {
        self.scene
    }

    /// Poses the scene's animations at time `t` (seconds); the next frame shows the pose.
    pub fn animate(&mut self, t: f32) -> Result<usize> {
        Ok(self.scene.animate(t)?)
    }

    /// The culler, for the scene as it is now: edits are propagated, and the culler is built
    /// on first use and synced after ([`Culler::sync`]), so what it answers outside a frame
    /// (its instances, an occluder pass) is never stale. Errors as [`Culler::sync`].
    pub fn culler(&mut self) -> Result<&mut Culler> {
        Ok(self.culler_and_scene()?.0)
    }

    /// [`World::culler`] beside the scene it culls: for what takes the two together
    /// (drawing a frame's wireframe, testing boxes).
    pub fn culler_and_scene(&mut self) -> Result<(&mut Culler, &Scene)> {
        self.propagate();
        let scene = &self.scene;
        let culler = self.culler.get_or_insert_with(|| Culler::new(scene));
        culler.sync(scene)?;
        Ok((culler, scene))
    }

    /// Builds what `method` draws with, if not built yet, for the scene as it is now (the
    /// culler for a culling method, the ray caster's BVHs for ray casting) and the drawn
    /// meshes' face records that flat shading reads ([`Mesh::faces`](sightline_scene::Mesh::faces),
    /// 24 bytes a triangle), so that the builds are not paid by the first frame.
    pub fn prepare(&mut self, method: impl Into<Visibility>) -> Result<()> {
        match method.into() {
            Visibility::Cull(m) => self.culler()?.prepare(m),
            Visibility::RayCast => {
                self.caster()?;
            }
        }
        // Only the meshes some node draws: a mesh kept in the store and drawn by none (a
        // file's unused mesh, say) would hold 24 bytes a triangle for nothing. Found from the
        // nodes, not from `Scene::instances`, whose records (128 bytes an instance) would
        // add to the peak memory of a scene of millions of instances.
        let mut drawn = SecondaryMap::<MeshId, ()>::new();
        for id in self.scene.depth_first() {
            if let Some(mesh) = self.scene.node(id).and_then(|n| n.mesh()) {
                drawn.insert(mesh, ());
            }
        }
        let meshes: Vec<&Mesh> = drawn.keys().filter_map(|id| self.scene.mesh(id)).collect();
        meshes.par_iter().for_each(|m| {
            m.faces();
        });
        Ok(())
    }

    /// Propagates pending edits, and drops the structures built for another scene (one put
    /// in place through [`World::scene_mut`]): they are built again for this one on use.
    fn propagate(&mut self) {
        self.scene.update_transforms();
        let id = self.scene.id();
        if self.culler.as_ref().is_some_and(|c| c.scene_id() != id) {
            self.culler = None;
        }
        if self.caster.as_ref().is_some_and(|c| c.scene_id() != id) {
            self.caster = None;
        }
    }

    /// Propagates pending edits and brings every structure built so far up to date: what
    /// the next frame would do first. A frame loop that times its frames apart from the
    /// scene's changes (as `sightline walk` does) calls it before the clock starts.
    pub fn update(&mut self) -> Result<()> {
        self.update_with(|w| {
            if let Some(c) = &mut w.culler {
                c.sync(&w.scene)?;
            }
            if let Some(c) = &mut w.caster {
                c.sync(&w.scene)?;
            }
            Ok(())
        })
    }

    /// Propagates pending edits, then runs `sync` (which brings structures up to date).
    /// With edits pending, the pool's other worker is kept awake through it all: an update
    /// is a run of short parallel steps between serial ones ([`with_helper_awake`]). Without,
    /// there is little to do, and waking the worker would only cost.
    fn update_with(&mut self, sync: impl FnOnce(&mut Self) -> Result<()> + Send) -> Result<()> {
        let update = |w: &mut Self| {
            w.propagate();
            sync(w)
        };
        if self.scene.needs_update() {
            with_helper_awake(|| update(self))
        } else {
            update(self)
        }
    }

    /// The ray caster (built on first use) beside the scene it casts, both up to date: for
    /// what takes the two together (a supersampled picture cast ray by ray).
    pub fn caster_and_scene(&mut self) -> Result<(&RayCaster, &Scene)> {
        self.caster()?;
        Ok((self.caster.as_ref().expect("built by caster()"), &self.scene))
    }

    /// The ray caster, built on first use, up to date with the propagated scene.
    fn caster(&mut self) -> Result<&mut RayCaster> {
        self.propagate();
        Ok(match &mut self.caster {
            Some(c) => {
                c.sync(&self.scene)?;
                c
            }
            slot => slot.insert(RayCaster::build(&self.scene)?),
        })
    }

    /// Renders the scene seen by `camera` with `method` into `fb` (every plane written);
    /// pending edits are propagated and the structures brought up to date first.
    pub fn render(
        &mut self,
        camera: &Camera,
        method: impl Into<Visibility>,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<FrameReport> {
        let t0 = std::time::Instant::now();
        let method = method.into();
        // The structure `method` draws with, built on first use and up to date.
        self.update_with(|w| match method {
            Visibility::Cull(_) => w.culler().map(|_| ()),
            Visibility::RayCast => w.caster().map(|_| ()),
        })?;
        let mut report = FrameReport::default();
        match method {
            Visibility::Cull(m) => {
                let culler = self.culler.as_mut().expect("built by culler() above");
                let (cs, fs) = culler.render(&self.scene, camera, m, fb, opts)?;
                report.cull = Some(cs);
                report.raster = Some(fs);
            }
            Visibility::RayCast => {
                let caster = self.caster.as_ref().expect("built by caster() above");
                report.rays = Some(caster.render(&self.scene, camera, fb, &RaycastOptions::from_render(opts))?);
            }
        }
        report.ms_total = t0.elapsed().as_secs_f64() * 1e3;
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use sightline_scene::{shapes, NodeDesc, NodeId, Transform};

    use super::*;
    use crate::SyncOutcome;

    /// A world of one unit cube at the origin, and the cube's node.
    fn one_cube() -> (World, NodeId) {
        let mut scene = Scene::new();
        let cube = scene.add_mesh(shapes::cube("cube").unwrap());
        let node = scene.add_node(None, NodeDesc::new("cube").mesh(cube)).unwrap();
        (World::new(scene), node)
    }

    /// A camera at `eye` looking at `target`, and a 16 × 16 framebuffer.
    fn view(eye: Vec3, target: Vec3) -> (Camera, Framebuffer) {
        let look = sightline_scene::LookAt { eye, target, ..Default::default() };
        (Camera::perspective(&look, 1.0).unwrap(), Framebuffer::new(16, 16).unwrap())
    }

    #[test]
    fn update_brings_every_built_structure_up_to_date_and_builds_none() {
        let (mut world, node) = one_cube();
        let unused = world.scene_mut().add_mesh(shapes::cube("unused").unwrap());
        world.update().unwrap();
        assert!(world.culler.is_none() && world.caster.is_none(), "update builds nothing");
        assert!(!world.scene().meshes().any(|(_, m)| m.has_faces()));
        world.prepare(Method::Hzb).unwrap();
        for (id, m) in world.scene().meshes() {
            assert_eq!(m.has_faces(), id != unused, "prepare makes the face records of the drawn meshes only");
        }
        world.prepare(Visibility::RayCast).unwrap();
        let moved = Transform::from_translation(Vec3::new(3.0, 0.0, 0.0));
        world.scene_mut().set_local_transform(node, moved).unwrap();
        world.update().unwrap();
        let World { scene, culler, caster } = &mut world;
        let culler = culler.as_mut().unwrap();
        assert_eq!(culler.instances()[0].world_from_local.translation.x, 3.0);
        assert_eq!(culler.sync(scene).unwrap(), SyncOutcome::Unchanged, "the culler was synced");
        assert!(!caster.as_mut().unwrap().sync(scene).unwrap(), "the ray caster was synced");
    }

    #[test]
    fn the_culler_outside_a_frame_follows_the_scene() {
        let (mut world, node) = one_cube();
        assert_eq!(world.culler().unwrap().instances()[0].world_from_local.translation.x, 0.0);
        let moved = Transform::from_translation(Vec3::new(3.0, 0.0, 0.0));
        world.scene_mut().set_local_transform(node, moved).unwrap();
        let (culler, _) = world.culler_and_scene().unwrap();
        assert_eq!(culler.instances()[0].world_from_local.translation.x, 3.0, "propagated and synced");
    }

    /// A scene of more triangles than 32-bit IDs can name is refused by every renderer with
    /// an error that gives the count, and the culler builds nothing for it.
    #[test]
    fn too_many_triangles_for_32_bit_ids_is_an_error() {
        use sightline_scene::{Mesh, MAX_DRAWN_TRIANGLES};
        let mut scene = Scene::new();
        // 2^20 degenerate triangles (cheap to make and never drawn), placed 4,100 times:
        // 4.3 × 10^9 triangles.
        let big = Mesh::new("big", vec![Vec3::ZERO; 3], None, None, vec![0; 3 << 20]).unwrap();
        let big = scene.add_mesh(big);
        for i in 0..4100 {
            scene.add_node(None, NodeDesc::new(format!("copy {i}")).mesh(big)).unwrap();
        }
        scene.update_transforms();
        let triangles = scene.drawn_triangle_count();
        assert!(triangles > MAX_DRAWN_TRIANGLES);
        let check = |e: crate::Error| {
            assert!(matches!(e, crate::Error::TooManyTriangles { triangles: t, .. } if t == triangles), "{e}");
            assert!(e.to_string().contains(&triangles.to_string()), "{e}");
        };
        let (camera, mut fb) = view(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO);
        let mut culler = Culler::new(&scene);
        assert!(culler.instances().is_empty(), "nothing built for a scene that cannot be drawn");
        check(culler.render(&scene, &camera, Method::Hzb, &mut fb, &RenderOptions::default()).unwrap_err());
        check(crate::RayCaster::build(&scene).unwrap_err());
        let mut world = World::new(scene);
        check(world.render(&camera, Method::Brute, &mut fb, &RenderOptions::default()).unwrap_err());
    }

    #[test]
    fn a_scene_put_in_place_gets_its_own_structures() {
        let scene_with = |x: f32| {
            let mut s = Scene::new();
            let cube = s.add_mesh(shapes::cube("cube").unwrap());
            s.add_node(None, NodeDesc::new("cube").mesh(cube).transform(Transform::from_translation(Vec3::X * x)))
                .unwrap();
            s
        };
        let mut world = World::new(scene_with(0.0));
        world.prepare(Method::Hzb).unwrap();
        world.prepare(Visibility::RayCast).unwrap();
        *world.scene_mut() = scene_with(4.0);
        world.update().unwrap();
        assert_eq!(world.culler().unwrap().instances()[0].world_from_local.translation.x, 4.0);
        let (camera, mut fb) = view(Vec3::new(4.0, 0.0, 5.0), Vec3::X * 4.0);
        world.render(&camera, Visibility::RayCast, &mut fb, &RenderOptions::default()).unwrap();
        assert_ne!(fb.ids[8 * 16 + 8], 0, "the ray caster sees the new scene's cube");
    }

    #[test]
    fn an_overflowing_world_transform_is_an_error_not_a_frame() {
        let mut scene = Scene::new();
        let cube = scene.add_mesh(shapes::cube("cube").unwrap());
        let big = Transform::from_scale(Vec3::splat(1e20));
        let a = scene.add_node(None, NodeDesc::new("a").transform(big)).unwrap();
        let b = scene.add_node(Some(a), NodeDesc::new("b").transform(big)).unwrap();
        scene.add_node(Some(b), NodeDesc::new("far cube").mesh(cube)).unwrap();
        let (camera, mut fb) = view(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO);
        let mut world = World::new(scene);
        for v in [Visibility::Cull(Method::Hzb), Visibility::RayCast] {
            let e = world.render(&camera, v, &mut fb, &RenderOptions::default()).unwrap_err().to_string();
            assert!(e.contains("overflows") && e.contains("node '"), "{e}");
        }
        world.scene_mut().set_local_transform(a, Transform::IDENTITY).unwrap();
        world.render(&camera, Method::Hzb, &mut fb, &RenderOptions::default()).unwrap();
    }
}

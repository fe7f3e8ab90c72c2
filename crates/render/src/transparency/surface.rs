//! A triangle's surface at any pixel, found from its ID: alpha (for the mask test) and color
//! (for blending), computed exactly as deferred shading computes an opaque pixel's color.
//!
//! The barycentric weights come from the 2D homogeneous rows of the deferred pass (Olano &
//! Greer, "Triangle Scan Conversion using 2D Homogeneous Coordinates", 1997), and the color
//! from the same [`TriangleShader`], so a blended surface of alpha 1 shows the very color
//! the z-buffer path would give it.

use glam::{Vec3, Vec3A};
use sightline_scene::{AlphaMode, Camera, Instance, Scene};

use crate::deferred::{ndc_x, ndc_y, Lookup, TriEntry};
use crate::shading::{InstanceShading, ShadeOptions, TriangleShader};

/// Finds and prepares the surfaces of triangle IDs for one frame.
pub(crate) struct Surfaces<'a> {
    lookup: Lookup<'a>,
    scene: &'a Scene,
    camera: &'a Camera,
    /// Shading options.
    pub opts: &'a ShadeOptions,
    sx: f32,
    sy: f32,
}

/// One triangle ready to give alpha and color at any pixel.
pub(crate) struct Surface<'a> {
    entry: TriEntry<'a>,
    /// The material's alpha mode.
    pub mode: AlphaMode,
}

impl<'a> Surfaces<'a> {
    /// Surfaces of the triangles of `instances` seen by `camera` on a `width × height`
    /// target.
    pub fn new(
        scene: &'a Scene,
        instances: &'a [Instance],
        camera: &'a Camera,
        opts: &'a ShadeOptions,
        (width, height): (u32, u32),
    ) -> Self {
        let (sx, sy) = (2.0 / width as f32, 2.0 / height as f32);
        Self { lookup: Lookup::new(instances), scene, camera, opts, sx, sy }
    }

    /// The surface of triangle ID `id` (`None` when no instance draws it); `hint` is the
    /// instance of the last call.
    pub fn get(&self, id: u32, hint: &mut u32) -> Option<Surface<'a>> {
        let g = id.checked_sub(1)?;
        let index = self.lookup.find_hinted(g, hint)?;
        let inst = &self.lookup.instances[index as usize];
        let mesh = self.scene.mesh(inst.mesh)?;
        let t = (g - inst.first_triangle) as usize;
        if t >= mesh.triangle_count() {
            return None;
        }
        let material = self.scene.instance_material(inst);
        let shading = InstanceShading::new(inst.world_from_local, material);
        let shader = TriangleShader::new(&shading, mesh, t, self.camera.view.eye, self.opts);
        let clip = self.camera.clip_from_local(&inst.world_from_local);
        Some(Surface { entry: TriEntry::new(&clip, mesh, t, shader), mode: material.alpha_mode })
    }

    /// The world-space barycentric weights of `s` at the center of pixel (x, y).
    #[inline]
    fn weights(&self, s: &Surface, x: i32, y: i32) -> Vec3 {
        let p = Vec3A::new(ndc_x(x as usize, self.sx), ndc_y(y as usize, self.sy), 1.0);
        s.entry.weights(p, self.opts.perspective_correct)
    }

    /// Whether the mask test keeps `s` at pixel (x, y): alpha at least the cutoff of a
    /// [`AlphaMode::Mask`] material (a NaN cutoff keeps nothing); other modes keep every
    /// point.
    #[inline]
    pub fn keeps(&self, s: &Surface, x: i32, y: i32) -> bool {
        match s.mode {
            AlphaMode::Mask { cutoff } => s.entry.shader.alpha(self.weights(s, x, y), self.opts) >= cutoff,
            _ => true,
        }
    }

    /// The shaded color of `s` at pixel (x, y), alpha included (RGBA8, as deferred shading
    /// would write it).
    #[inline]
    pub fn color(&self, s: &Surface, x: i32, y: i32) -> [u8; 4] {
        match s.entry.shader.constant() {
            Some(c) => c,
            None => s.entry.shader.shade(self.weights(s, x, y), self.opts),
        }
    }
}

//! The framebuffer: color, depth and triangle-ID planes of one size, row 0 at the top.
//!
//! Depth holds window z in [0, 1] (cleared to 1.0, smaller is nearer, test LESS); the ID
//! plane holds 0 for background and otherwise `1 + global triangle index` in the flattened
//! scene order (see [`triangle_id`]). Color, depth and ID are written together on a passed
//! depth test.

use crate::plane::Plane;
use crate::{Error, Result};

/// Largest accepted side length.
pub const MAX_SIZE: u32 = 8192;

/// Color, depth and triangle ID per pixel, plus an optional depth-test counter. Each plane
/// is a [`Plane`]: a slice of one value per pixel (row-major, row 0 at the top) whose memory
/// starts on a cache line, which the tile stage's writes rely on for speed. Every plane
/// holds width × height values; drawing into a framebuffer one of whose planes (color,
/// depth, IDs or counts) was replaced by a plane of another length panics, naming the size.
#[derive(Debug, Clone)]
pub struct Framebuffer {
    width: u32,
    height: u32,
    /// RGBA8 per pixel, row-major, row 0 at the top.
    pub color: Plane<[u8; 4]>,
    /// Window depth per pixel.
    pub depth: Plane<f32>,
    /// Triangle ID per pixel (0 = background).
    pub ids: Plane<u32>,
    /// Depth tests per pixel (depth complexity), when counting is on.
    pub depth_tests: Option<Plane<u32>>,
}

impl Framebuffer {
    /// A cleared framebuffer; errors on a zero or too large size.
    pub fn new(width: u32, height: u32) -> Result<Self> {
        if width == 0 || height == 0 || width > MAX_SIZE || height > MAX_SIZE {
            return Err(Error::InvalidSize { width, height });
        }
        let n = width as usize * height as usize;
        Ok(Self {
            width,
            height,
            color: Plane::filled(n, [0, 0, 0, 255]),
            depth: Plane::filled(n, 1.0),
            ids: Plane::filled(n, 0),
            depth_tests: None,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.ids.len()
    }
    /// Always false: a framebuffer has at least one pixel.
    pub fn is_empty(&self) -> bool {
        false
    }
    /// Index of pixel (x, y) in the planes.
    #[inline]
    pub fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }
    /// Panics, naming the size, unless every plane holds width × height values. The planes
    /// are public fields, so a caller could have replaced one; the drawing and shading loops
    /// walk them in bands of rows and would otherwise stop short or reach past one's end.
    pub(crate) fn assert_planes(&self) {
        let (w, h) = (self.width, self.height);
        let n = self.len();
        assert!(
            self.color.len() == n
                && self.depth.len() == n
                && self.ids.len() == n
                && self.depth_tests.as_ref().is_none_or(|c| c.len() == n),
            "a framebuffer plane does not hold {w} × {h} values"
        );
    }
    /// Turns per-pixel depth-test counting on or off (off by default: it costs a write per test).
    pub fn count_depth_tests(&mut self, on: bool) {
        self.depth_tests = on.then(|| Plane::filled(self.len(), 0));
    }
    /// Clears color to `background`, depth to 1.0, IDs to 0 and the counters to 0.
    pub fn clear(&mut self, background: [u8; 4]) {
        use rayon::prelude::*;
        // 12 bytes a pixel: worth both cores at 1280×720 and up.
        const ROWS: usize = 64 * 1024;
        self.color.par_chunks_mut(ROWS).for_each(|c| c.fill(background));
        self.depth.par_chunks_mut(ROWS).for_each(|c| c.fill(1.0));
        self.ids.par_chunks_mut(ROWS).for_each(|c| c.fill(0));
        if let Some(c) = &mut self.depth_tests {
            c.par_chunks_mut(ROWS).for_each(|c| c.fill(0));
        }
    }
}

/// The ID a triangle writes: 1 + its index in the flattened scene order (0 is background).
#[inline]
pub fn triangle_id(instance_first_triangle: u32, triangle: u32) -> u32 {
    instance_first_triangle + triangle + 1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_checked() {
        assert!(Framebuffer::new(0, 10).is_err());
        assert!(Framebuffer::new(10, 0).is_err());
        assert!(Framebuffer::new(8193, 1).is_err());
        let f = Framebuffer::new(1, 1).unwrap();
        assert_eq!((f.len(), f.depth[0], f.ids[0]), (1, 1.0, 0));
    }

    /// The planes are public: one replaced by a plane of another length is caught before
    /// the tile stage writes through raw pointers.
    #[test]
    #[should_panic(expected = "does not hold")]
    fn a_replaced_plane_of_the_wrong_length_is_caught_before_drawing() {
        use glam::Vec4;
        let mut fb = Framebuffer::new(64, 64).unwrap();
        fb.ids = Plane::filled(10, 0);
        let tri = [[Vec4::new(-1.0, -1.0, 0.0, 1.0), Vec4::new(1.0, -1.0, 0.0, 1.0), Vec4::new(0.0, 1.0, 0.0, 1.0)]];
        crate::Renderer::new().draw_clip_triangles(&tri, 1, &mut fb, &crate::RenderOptions::default());
    }

    /// The color plane too, where the shading pass writes it: a short one is caught, not
    /// left partly unshaded.
    #[test]
    #[should_panic(expected = "does not hold")]
    fn a_replaced_color_plane_of_the_wrong_length_is_caught_before_shading() {
        let mut fb = Framebuffer::new(64, 64).unwrap();
        fb.color = Plane::filled(64, [0, 0, 0, 255]);
        let scene = sightline_scene::Scene::new();
        let look = sightline_scene::LookAt { target: glam::Vec3::NEG_Z, ..Default::default() };
        let camera = sightline_scene::Camera::perspective(&look, 1.0).unwrap();
        crate::shade_pass(&scene, &[], &camera, &mut fb, &crate::ShadeOptions::default(), [0, 0, 0, 255]);
    }
}

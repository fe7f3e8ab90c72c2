//! The sky behind the scene: a gradient painted where no surface was drawn (triangle ID
//! 0), by both renderers alike.
//!
//! The color depends on the elevation of the view ray, the sine of its angle above the
//! horizontal plane: the horizon color at 0, blending into the zenith color going up and,
//! quickly, into the ground color going down — the usual stand-in for atmospheric
//! scattering in an unlit background (a "gradient sky"; Akenine-Möller, Haines & Hoffman,
//! *Real-Time Rendering*, 4th ed., 2018, on skyboxes and sky rendering). One
//! elevation is taken per image row, through the row's middle column: a row is then one
//! color, so painting it costs what a flat clear costs, and with the camera's up along +y
//! the rows follow the horizon line exactly where it is drawn. Parallel projections have
//! one ray direction for the whole image, hence one color.
//!
//! Only colors change: the background keeps ID 0 and depth 1.0.

use glam::{Vec2, Vec3};
use serde::Serialize;
use sightline_scene::Camera;

use crate::color::to_rgba8;
use crate::Framebuffer;

/// A gradient sky (linear RGB colors in [0, 1]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sky {
    /// Straight up.
    pub zenith: [f32; 3],
    /// At the horizon.
    pub horizon: [f32; 3],
    /// Below the horizon (seen where no ground is drawn).
    pub ground: [f32; 3],
}

impl Default for Sky {
    /// A clear late afternoon: deep blue overhead, a warm haze at the horizon.
    fn default() -> Self {
        Sky { zenith: [0.16, 0.33, 0.66], horizon: [0.88, 0.80, 0.70], ground: [0.38, 0.37, 0.38] }
    }
}

impl Sky {
    /// The color of a view ray whose elevation has sine `up` (−1 straight down, 1 straight
    /// up); NaN counts as the horizon.
    pub fn color(&self, up: f32) -> [u8; 4] {
        let up = if up.is_nan() { 0.0 } else { up.clamp(-1.0, 1.0) };
        let (h, z, g) = (Vec3::from(self.horizon), Vec3::from(self.zenith), Vec3::from(self.ground));
        // The haze thins fast just above the horizon, then slowly (a square root).
        let c = if up >= 0.0 { h.lerp(z, up.sqrt()) } else { h.lerp(g, (-up * 6.0).min(1.0)) };
        to_rgba8(c.extend(1.0))
    }

    /// The color of each of the `height` rows of an image seen by `camera`.
    pub fn rows(&self, camera: &Camera, height: usize) -> Vec<[u8; 4]> {
        let sy = 2.0 / height.max(1) as f32;
        (0..height)
            .map(|y| {
                let (_, dir) = camera.ray_through_ndc(Vec2::new(0.0, 1.0 - (y as f32 + 0.5) * sy));
                self.color(dir.normalize_or_zero().y)
            })
            .collect()
    }

    /// Paints the background pixels (ID 0) of `fb`, seen by `camera`, with the sky.
    pub fn paint(&self, camera: &Camera, fb: &mut Framebuffer) {
        use rayon::prelude::*;
        let w = fb.width() as usize;
        let rows = self.rows(camera, fb.height() as usize);
        fb.color.par_chunks_mut(w).zip(fb.ids.par_chunks(w)).zip(rows).for_each(|((color, ids), sky)| {
            for (c, &id) in color.iter_mut().zip(ids) {
                if id == 0 {
                    *c = sky;
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sightline_scene::{Angle, LookAt};

    #[test]
    fn gradient_from_ground_through_horizon_to_zenith() {
        let s = Sky::default();
        assert_eq!(s.color(0.0), to_rgba8(Vec3::from(s.horizon).extend(1.0)));
        assert_eq!(s.color(1.0), to_rgba8(Vec3::from(s.zenith).extend(1.0)));
        assert_eq!(s.color(-1.0), to_rgba8(Vec3::from(s.ground).extend(1.0)));
        assert_eq!(s.color(f32::NAN), s.color(0.0));
        // Blue grows going up.
        assert!(s.color(0.1)[2] < s.color(0.5)[2] || s.horizon[2] > s.zenith[2]);
    }

    #[test]
    fn rows_of_a_level_camera_darken_towards_the_top_and_meet_the_horizon_mid_image() {
        let look = LookAt { eye: Vec3::new(0.0, 2.0, 0.0), target: Vec3::new(0.0, 2.0, -10.0), ..LookAt::default() };
        let look = LookAt { fovy: Angle::degrees(60.0), ..look };
        let cam = Camera::perspective(&look, 1.0).unwrap();
        let rows = Sky::default().rows(&cam, 64);
        let horizon = Sky::default().color(0.0);
        // Rows 31 and 32 straddle the horizon.
        let near_horizon = |c: [u8; 4]| c.iter().zip(horizon).all(|(&a, b)| a.abs_diff(b) <= 40);
        assert!(near_horizon(rows[31]) && near_horizon(rows[32]));
        assert!(rows[0][2] != rows[31][2], "the top is not the horizon");
        // 30° up at the top row, 30° down at the bottom one.
        let (top, bottom) = (Sky::default().color(0.49), Sky::default().color(-0.49));
        let close = |a: [u8; 4], b: [u8; 4]| a.iter().zip(b).all(|(&x, y)| x.abs_diff(y) <= 3);
        assert!(close(rows[0], top) && close(rows[63], bottom), "{:?} {:?}", rows[0], rows[63]);
    }

    #[test]
    fn paint_changes_only_background_colors() {
        let mut fb = Framebuffer::new(4, 4).unwrap();
        fb.clear([1, 2, 3, 255]);
        fb.ids[5] = 7;
        fb.color[5] = [9, 9, 9, 255];
        let look = LookAt { eye: Vec3::ZERO, target: Vec3::new(0.0, 0.0, -1.0), ..LookAt::default() };
        let cam = Camera::perspective(&look, 1.0).unwrap();
        let (depth, ids) = (fb.depth.clone(), fb.ids.clone());
        Sky::default().paint(&cam, &mut fb);
        assert_eq!((fb.depth.clone(), fb.ids.clone()), (depth, ids));
        assert_eq!(fb.color[5], [9, 9, 9, 255]);
        assert!(fb.color.iter().enumerate().all(|(i, &c)| i == 5 || c != [1, 2, 3, 255]));
    }
}

//! A frame session: many draw batches into one frame, with the z-pyramid of what is drawn
//! so far available between batches — what an occlusion culler needs (draw the nearest
//! occluders, test the next boxes against their pyramid, draw what survives, repeat).
//!
//! The session is a guard: [`Renderer::begin`] returns it, borrowing the framebuffer it
//! draws into; it draws ([`Session::draw`], [`Session::draw_sources`],
//! [`Session::draw_clip_triangles`]),
//! answers [`Session::pyramid`], and [`Session::finish`] completes the frame. The
//! framebuffer holds the frame's depth and IDs between batches and the renderer's tiles
//! the pyramid's levels over them: each batch draws a tile in a worker's scratch buffer
//! (cleared on the tile's first use, else loaded from the framebuffer) and writes it back
//! right after, while it is in the core's cache; `finish` writes only the tiles no batch
//! touched, as cleared. (Writing every tile out at the end
//! instead read the frame's 7.5 MB of tile buffers back from the shared cache: 0.37 ms of
//! the 1.9 ms the street path's oracle frame took in a session on two threads.) While the
//! session lives the renderer and the framebuffer can do nothing else; dropped without
//! `finish`, the framebuffer holds the tiles drawn so far and its other pixels as they
//! were. The depth format and every other option come from the options given to `begin`,
//! for every batch.

use glam::Vec4;
use sightline_scene::{Camera, Instance, Scene};

use crate::geometry::DrawList;
use crate::hzb::TilePyramid;
use crate::options::{DrawItem, DrawSource, RenderOptions};
use crate::pipeline::{Renderer, Target};
use crate::{FrameStats, Framebuffer, Result};

/// An open frame session of a [`Renderer`] on a [`Framebuffer`]; see the module doc.
#[derive(Debug)]
pub struct Session<'r> {
    renderer: &'r mut Renderer,
    fb: &'r mut Framebuffer,
    opts: RenderOptions,
}

impl Renderer {
    /// Begins a frame session drawing into `fb` (its size, and whether it counts depth
    /// tests) with `opts`. `fb` needs no clear: by [`Session::finish`] every pixel's depth
    /// and ID (and depth-test count when counting) is written; its colors are left as they
    /// were.
    pub fn begin<'r>(&'r mut self, fb: &'r mut Framebuffer, opts: &RenderOptions) -> Session<'r> {
        self.start_session(fb.width(), fb.height());
        Session { renderer: self, fb, opts: *opts }
    }
}

impl<'r> Session<'r> {
    /// The options every draw of this session uses.
    pub fn options(&self) -> &RenderOptions {
        &self.opts
    }

    /// The renderer, the session's draw target and the options, for one batch.
    fn batch(&mut self) -> (&mut Renderer, Target<'_>, RenderOptions) {
        (&mut *self.renderer, Target::Session { fb: &mut *self.fb }, self.opts)
    }

    /// Draws triangle ranges of the scene's instances into the session's frame, in order,
    /// like [`Renderer::draw`].
    pub fn draw(
        &mut self,
        scene: &Scene,
        instances: &[Instance],
        items: &[DrawItem],
        camera: &Camera,
    ) -> Result<FrameStats> {
        let (renderer, target, opts) = self.batch();
        renderer.draw_items(scene, instances, items, camera, target, &opts)
    }

    /// Draws triangle ranges of indexed geometry into the session's frame, in order, like
    /// [`Renderer::draw_sources`].
    pub fn draw_sources(&mut self, sources: &[DrawSource], camera: &Camera) -> Result<FrameStats> {
        self.draw_sources_checked(sources, camera, true)
    }

    /// [`Session::draw_sources`]; `check_indices = false` for sources in range by
    /// construction (see [`Renderer::draw_sources_to`]).
    pub(crate) fn draw_sources_checked(
        &mut self,
        sources: &[DrawSource],
        camera: &Camera,
        check_indices: bool,
    ) -> Result<FrameStats> {
        let (renderer, target, opts) = self.batch();
        renderer.draw_sources_to(sources, camera, target, &opts, check_indices)
    }

    /// Draws the pieces `ranges` of `list` into the session's frame, in order
    /// ([`Renderer::draw_list_to`]).
    pub(crate) fn draw_list<L: DrawList + ?Sized>(
        &mut self,
        list: &L,
        ranges: &[(u32, u32, u32)],
        camera: &Camera,
    ) -> Result<FrameStats> {
        let (renderer, target, opts) = self.batch();
        renderer.draw_list_to(list, ranges, camera, target, &opts)
    }

    /// Draws raw clip-space triangles into the session's frame, triangle `k` with ID
    /// `first_id + k`, like [`Renderer::draw_clip_triangles`].
    pub fn draw_clip_triangles(&mut self, triangles: &[[Vec4; 3]], first_id: u32) -> FrameStats {
        let (renderer, target, opts) = self.batch();
        renderer.draw_clip_to(triangles, first_id, target, &opts)
    }

    /// The z-pyramid of the frame drawn so far.
    pub fn pyramid(&self) -> TilePyramid<'_> {
        let depth = &self.fb.depth;
        self.renderer.session_pyramid(depth, self.opts.depth_format).expect("a session has its tile grid from `begin`")
    }

    /// Ends the session: the framebuffer's pixels no batch drew into are written as
    /// cleared (depth 1, ID 0, no depth tests), the others hold what the batches drew.
    /// Returns the pixels covered (ID ≠ 0).
    pub fn finish(self) -> u64 {
        self.renderer.finish_session(self.fb, self.opts.depth_format)
    }

    /// The renderer, for tests that look at its tiles.
    #[cfg(test)]
    pub(crate) fn renderer(&self) -> &Renderer {
        self.renderer
    }

    /// The framebuffer, for tests that look at what the tiles wrote through.
    #[cfg(test)]
    pub(crate) fn framebuffer(&self) -> &Framebuffer {
        self.fb
    }
}

#[cfg(test)]
mod tests;

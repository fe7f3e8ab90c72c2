//! A frame session: many draw batches into one frame held in the renderer's tiles, with
//! the z-pyramid of what is drawn so far available between batches — what an occlusion
//! culler needs (draw the nearest occluders, test the next boxes against their pyramid,
//! draw what survives, repeat).
//!
//! The session is a guard: [`Renderer::begin`] returns it, it draws
//! ([`Session::draw_sources`], [`Session::draw_clip_triangles`]), answers
//! [`Session::pyramid`], and [`Session::finish`] writes the frame into a framebuffer. While
//! it lives the renderer can do nothing else; dropped without `finish`, the frame is
//! abandoned unwritten. The depth format and every other option come from the options
//! given to `begin`, for every batch.

use glam::Vec4;
use sightline_scene::Camera;

use crate::hzb::TilePyramid;
use crate::options::{DrawSource, RenderOptions};
use crate::pipeline::{Renderer, Target};
use crate::{Error, FrameStats, Framebuffer, Result};

/// An open frame session of a [`Renderer`]; see the module doc.
#[derive(Debug)]
pub struct Session<'r> {
    renderer: &'r mut Renderer,
    opts: RenderOptions,
    width: u32,
    height: u32,
    counting: bool,
}

impl Renderer {
    /// Begins a frame session for a framebuffer like `fb` (its size, and whether it counts
    /// depth tests), drawing with `opts`. `fb` needs no clear: [`Session::finish`] writes
    /// every pixel.
    pub fn begin(&mut self, fb: &Framebuffer, opts: &RenderOptions) -> Session<'_> {
        let (width, height) = (fb.width(), fb.height());
        self.start_session(width, height);
        Session { renderer: self, opts: *opts, width, height, counting: fb.depth_tests.is_some() }
    }
}

impl<'r> Session<'r> {
    /// The options every draw of this session uses.
    pub fn options(&self) -> &RenderOptions {
        &self.opts
    }

    fn target(&self) -> Target<'static> {
        Target::Session {
            width: self.width,
            height: self.height,
            counting: self.counting,
            format: self.opts.depth_format,
        }
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
        let target = self.target();
        self.renderer.draw_sources_to(sources, camera, target, &self.opts, check_indices)
    }

    /// Draws raw clip-space triangles into the session's frame, triangle `k` with ID
    /// `first_id + k`, like [`Renderer::draw_clip_triangles`].
    pub fn draw_clip_triangles(&mut self, triangles: &[[Vec4; 3]], first_id: u32) -> FrameStats {
        let target = self.target();
        self.renderer.draw_clip_to(triangles, first_id, target, &self.opts)
    }

    /// The z-pyramid of the frame drawn so far.
    pub fn pyramid(&self) -> TilePyramid<'_> {
        self.renderer.session_pyramid(self.opts.depth_format).expect("a session has its tile grid from `begin`")
    }

    /// Ends the session: the frame's depth, IDs (and depth-test counts when counting) go to
    /// `fb`, every pixel of it; its colors are left as they were. Returns the pixels covered
    /// (ID ≠ 0). `fb` must have the size the session began with.
    pub fn finish(self, fb: &mut Framebuffer) -> Result<u64> {
        if (fb.width(), fb.height()) != (self.width, self.height) {
            return Err(Error::InvalidDraw(format!(
                "a session begun for {}x{} cannot finish into a {}x{} framebuffer",
                self.width,
                self.height,
                fb.width(),
                fb.height()
            )));
        }
        if fb.depth_tests.is_some() != self.counting {
            fb.count_depth_tests(self.counting);
        }
        Ok(self.renderer.store_session(fb, self.opts.depth_format))
    }

    /// The renderer, for tests that look at its tiles.
    #[cfg(test)]
    pub(crate) fn renderer(&self) -> &Renderer {
        self.renderer
    }
}

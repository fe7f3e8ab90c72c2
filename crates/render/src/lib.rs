//! # sightline-render
//!
//! Two ways to decide visibility and draw it on the CPU: an object-order rasterizer
//! (homogeneous clipping, watertight edge-function rasterization, z-buffer and a hierarchical
//! z-buffer for occlusion culling) and an image-order ray caster over a two-level BVH. Both
//! write the same [`Framebuffer`]: color, window depth and triangle IDs.

#![warn(missing_docs)]

mod error;
mod framebuffer;

pub use error::{Error, Result};
pub use framebuffer::{triangle_id, Framebuffer, MAX_SIZE};

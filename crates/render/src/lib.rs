//! # sightline-render
//!
//! Two ways to decide visibility and draw it on the CPU: an object-order rasterizer
//! (homogeneous clipping, watertight edge-function rasterization, z-buffer and a hierarchical
//! z-buffer for occlusion culling) and an image-order ray caster over a two-level BVH. Both
//! write the same [`Framebuffer`]: color, window depth and triangle IDs.

#![warn(missing_docs)]
// `!(x > 0.0)` is how this code says "not positive, or NaN": the negated comparison is the point.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod aa;
mod awake;
mod bin;
mod claim;
pub mod clip;
mod clip_matrix;
mod color;
pub mod csg;
pub mod cull;
mod deferred;
pub mod depth;
mod edge;
mod error;
mod forward;
mod framebuffer;
mod geometry;
pub mod hzb;
mod options;
pub mod output;
mod pipeline;
mod plane;
mod raster;
pub mod raycast;
mod session;
mod setup;
pub mod shading;
pub mod sky;
mod stats;
mod stream;
pub mod texture;
mod tiling;
pub mod transparency;
pub mod visibility;
pub mod wire;
mod world;

pub use error::{Error, Result};
pub use framebuffer::{triangle_id, Framebuffer, MAX_SIZE};
pub use plane::{Plane, PlaneValue};
pub use world::{FrameReport, Visibility, World};

pub use cull::{
    compare_ids, BoxVisibility, CullStats, Culler, Method, Mismatch, OccluderPass, OcclusionQueries, SyncOutcome,
};
pub use deferred::shade_pass;
pub use depth::DepthFormat;
pub use options::{draw_all, Antialias, DrawItem, DrawSource, RenderOptions, Wireframe};
pub use pipeline::{render_scene, Renderer};
pub use raycast::{RayCaster, RaycastOptions, RaycastStats};
pub use session::Session;
pub use shading::{shade, ShadeOptions, ShadingMode};
pub use sky::Sky;
pub use stats::FrameStats;
pub use transparency::{render_abuffer, render_depth_peeling, scene_has_transparency, Transparency, TransparencyStats};

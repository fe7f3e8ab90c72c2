//! The render crate's integration tests, one binary, so that cargo compiles and links one
//! test executable per package instead of one per file. `raster_*` test the rasterizer through
//! the public API, `raycast_*` the ray caster, `csg_raycast` CSG solids, `visibility_*` and
//! `warnock` the visibility lab's methods against the z-buffer, `wire_*` the wireframe,
//! `transparency` masked and blended materials.

#![forbid(unsafe_code)]

mod csg_raycast;
mod pictures;
mod raster_api;
mod raster_clipping;
mod raster_depth;
mod raster_determinism;
mod raster_fillrule;
mod raster_perspective;
mod raster_robustness;
mod raycast_agreement;
mod raycast_determinism;
mod raycast_reference;
mod raycast_robustness;
mod raycast_watertight;
mod support;
mod transparency;
mod visibility_lab;
mod visibility_robustness;
mod warnock;
mod wire_hidden_line;

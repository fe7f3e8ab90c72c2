//! The root package's integration tests, one binary, so that cargo compiles and links one
//! test executable per package instead of one per file. Each module is one subject:
//!
//! * `city_builder`: the library example builds its scene, writes its picture, prints statistics;
//! * `cli`: the built program: usage errors, file cameras, loader warnings;
//! * `culling`: every culling method draws exactly the brute-force triangle IDs;
//! * `culling_proptest`: conservative frustum culling, property-tested against the rasterizer;
//! * `lab`: `sightline lab` writes its pictures, table and JSON, and refuses methods over their limits;
//! * `occlusion`: occlusion queries against the z-pyramid, and the pyramid's exactness;
//! * `shards`: a walk in two shards, merged, is the report of one run;
//! * `viewer`: the interactive viewer in a real (virtual) window draws what `render` draws;
//! * `walkthrough`: the headless walkthrough writes its frames, GIF and CSV.
//!
//! proptest keeps the regression seeds of a module `m` of this binary in
//! `tests/proptest-regressions/m.txt` (commit them).

#![forbid(unsafe_code)]

mod city_builder;
mod cli;
mod culling;
mod culling_proptest;
mod lab;
mod moving;
mod occlusion;
mod shards;
mod support;
mod viewer;
mod walkthrough;

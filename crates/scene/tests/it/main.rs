//! The scene crate's integration tests, one binary, so that cargo compiles and links one
//! test executable per package instead of one per file: the scene graph and its change
//! reports, cameras, the loaders and the exporter, material alpha modes, broken glTF files, hostile asset
//! references, loader fuzzing, shared subgraphs (instantiate, prefabs, glTF DAGs), animation, the fuzz corpus replayed, and an
//! ignored 10^6-triangle round trip.
//!
//! proptest keeps the regression seeds of a module `m` of this binary in
//! `tests/proptest-regressions/m.txt` (commit them).

#![forbid(unsafe_code)]

mod alpha_modes;
mod animation;
mod broken_gltf;
mod cameras;
mod changes;
mod changes_replay;
mod fuzz_replay;
mod graph;
mod hostile_assets;
mod loader_fuzz;
mod loaders;
mod obj_round_trip;
mod shared;
mod support;

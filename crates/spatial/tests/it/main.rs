//! The spatial crate's integration tests, one binary, so that cargo compiles and links one
//! test executable per package instead of one per file: bad input, conservative culling
//! property-tested against a brute-force ray reference, and BVH builds over coincident or
//! evenly spaced geometry.
//!
//! proptest keeps the regression seeds of a module `m` of this binary in
//! `tests/proptest-regressions/m.txt` (commit them).

#![forbid(unsafe_code)]

mod bad_input;
mod conservative_culling;
mod degenerate_builds;

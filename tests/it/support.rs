//! Fixtures shared by the modules of this test binary.

use std::path::{Path, PathBuf};

use sightline::scene::path::CameraKey;

/// A look-at camera key with +y up.
pub fn camera_key(eye: [f32; 3], target: [f32; 3], fovy_deg: f32, near: f32, far: f32) -> CameraKey {
    CameraKey { eye, target, up: [0.0, 1.0, 0.0], fovy_deg, near, far }
}

/// An example program cargo built beside this test: `<target>/<profile>/examples/NAME` (the
/// test runs from `<target>/<profile>/deps`).
pub fn example_binary(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the test knows its own path");
    let profile_dir = exe.parent().and_then(Path::parent).expect("the test runs from <target>/<profile>/deps");
    let bin = profile_dir.join("examples").join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        bin.is_file(),
        "{} is missing: `cargo test` builds the examples; after a narrower command run `cargo build --example {name}`",
        bin.display()
    );
    bin
}

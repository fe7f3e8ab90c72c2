//! Fixtures shared by the modules of this test binary.

use std::path::{Path, PathBuf};

/// The path of a file in the repository's `assets` folder.
pub fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets").join(name)
}

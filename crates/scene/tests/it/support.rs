//! Fixtures shared by the modules of this test binary: the assets folder, error-message
//! checks, a minimal OBJ.

use std::path::{Path, PathBuf};

use sightline_scene::{Result, Scene};

/// The three vertices of one triangle, as OBJ `v` lines.
pub const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

/// The path of a file in the repository's `assets` folder.
pub fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets").join(name)
}

/// The error's text; panics when the load succeeded.
pub fn err_text(r: Result<Scene>) -> String {
    match r {
        Ok(s) => {
            panic!("expected an error, got a scene with {} nodes, {} triangles", s.node_count(), s.stats().triangles)
        }
        Err(e) => e.to_string(),
    }
}

/// Asserts that `msg` contains every one of `parts`.
pub fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "message {msg:?} does not mention {p:?}");
    }
}

//! Fixtures shared by the modules of this test binary: the assets folder, error-message
//! checks, a minimal OBJ.

use std::path::{Path, PathBuf};

use glam::Vec3;
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

/// A fresh, empty folder for one test.
pub fn tmp_dir(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sightline-loaders-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Every drawn triangle's world-space corners, in flattened (triangle ID) order.
pub fn world_triangles(scene: &Scene) -> Vec<[Vec3; 3]> {
    let mut out = Vec::new();
    for inst in scene.instances() {
        let mesh = scene.mesh(inst.mesh).unwrap();
        for t in 0..mesh.triangle_count() {
            out.push(mesh.triangle_positions(t).map(|p| inst.world_from_local.transform_point3(p)));
        }
    }
    out
}

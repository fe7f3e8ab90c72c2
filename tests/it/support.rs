//! Fixtures shared by the modules of this test binary.

use sightline::scene::path::CameraKey;

/// A look-at camera key with +y up.
pub fn camera_key(eye: [f32; 3], target: [f32; 3], fovy_deg: f32, near: f32, far: f32) -> CameraKey {
    CameraKey { eye, target, up: [0.0, 1.0, 0.0], fovy_deg, near, far }
}

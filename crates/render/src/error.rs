//! The render crate's error type.

/// What can go wrong when setting up or running a render.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A framebuffer size outside 1×1 ..= 8192×8192.
    #[error("invalid framebuffer size {width}x{height}: each side must be between 1 and 8192")]
    InvalidSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
    },
    /// An error from the scene (stale handle, bad camera, ...).
    #[error(transparent)]
    Scene(#[from] sightline_scene::Error),
    /// A draw list entry that does not fit the instances or meshes given.
    #[error("invalid draw item: {0}")]
    InvalidDraw(String),
    /// Writing an output file failed.
    #[error("{path}: {why}")]
    Output {
        /// The file.
        path: String,
        /// What went wrong.
        why: String,
    },
}

/// Result alias for the render crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

//! The scene crate's error type: every failure names the object or file and what is wrong.

use std::path::PathBuf;

/// Everything that can go wrong while building, editing or loading a scene.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A node handle that was removed (or never belonged to this scene).
    #[error("stale node handle {0:?}: the node was removed or belongs to another scene")]
    StaleNode(crate::NodeId),
    /// A mesh handle that is not in the mesh store.
    #[error("stale mesh handle {0:?}: the mesh was removed or belongs to another scene")]
    StaleMesh(crate::MeshId),
    /// A material handle that is not in the material store.
    #[error("stale material handle {0:?}")]
    StaleMaterial(crate::MaterialId),
    /// `set_parent` would make a node its own ancestor.
    #[error(
        "reparenting node '{child_name}' under node '{parent_name}' would create a cycle in the hierarchy: '{parent_name}' is '{child_name}' or one of its descendants"
    )]
    Cycle {
        /// The node being moved.
        child: crate::NodeId,
        /// The requested new parent (a descendant of `child`, or `child` itself).
        parent: crate::NodeId,
        /// The moved node's name.
        child_name: String,
        /// The requested parent's name.
        parent_name: String,
    },
    /// A transform with NaN or infinite entries, or one that cannot be inverted when it must be.
    #[error("invalid transform for {what}: {why}")]
    InvalidTransform {
        /// The object whose transform is wrong.
        what: String,
        /// What is wrong with it.
        why: String,
    },
    /// A mesh that fails validation.
    #[error("invalid mesh '{name}': {why}")]
    InvalidMesh {
        /// The mesh name.
        name: String,
        /// What is wrong with it.
        why: String,
    },
    /// A camera or projection with impossible parameters.
    #[error("invalid camera: {0}")]
    InvalidCamera(String),
    /// A camera asked for by index that the scene does not have.
    #[error("{}", no_such_camera(*index, *count))]
    NoSuchCamera {
        /// The index asked for.
        index: usize,
        /// How many cameras the scene has.
        count: usize,
    },
    /// An animation that cannot be played: a bad time, a channel aimed at a removed node.
    #[error("animation '{name}': {why}")]
    Animation {
        /// The animation's name.
        name: String,
        /// What is wrong.
        why: String,
    },
    /// A [`Prefab`](crate::Prefab) placed in a scene other than the one it was added to.
    #[error(
        "prefab '{prefab}' belongs to another scene (its meshes and materials live there): add it to this scene with Scene::add_prefab"
    )]
    ForeignPrefab {
        /// The prefab's name.
        prefab: String,
    },
    /// A builder called with parameters it cannot honour.
    #[error("invalid builder parameters: {0}")]
    InvalidParams(String),
    /// A file that could not be read or parsed.
    #[error("{}: {why}", path.display())]
    Load {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        why: String,
    },
    /// An I/O failure while writing a file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

/// Result alias for the scene crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// A load error for `path` with a message.
    pub fn load(path: impl Into<PathBuf>, why: impl Into<String>) -> Self {
        Error::Load { path: path.into(), why: why.into() }
    }
}

fn no_such_camera(index: usize, count: usize) -> String {
    match count {
        0 => format!("camera {index}: the scene has no cameras"),
        1 => format!("camera {index}: the scene has 1 camera (number 0)"),
        n => format!("camera {index}: the scene has {n} cameras (numbered 0 to {})", n - 1),
    }
}

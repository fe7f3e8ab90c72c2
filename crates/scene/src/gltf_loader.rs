//! TODO
use crate::{Error, Result, Scene};
/// Loads glTF.
pub fn load_gltf(path: &std::path::Path) -> Result<Scene> {
    Err(Error::load(path, "glTF loading not implemented yet"))
}

//! TODO
use crate::{Error, Result, Scene};
/// Loads OBJ.
pub fn load_obj(path: &std::path::Path) -> Result<Scene> {
    Err(Error::load(path, "OBJ loading not implemented yet"))
}

//! `sightline path` and `sightline export-obj`.

use std::path::Path;

use anyhow::{Context, Result};

use super::SceneArg;

/// Which camera path.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum PathKind {
    /// A walk at eye height (1.7) along the streets
    Street,
    /// A flight above the roofs
    Aerial,
    /// One turn around the scene at the three-quarter view's height, looking at its center
    Orbit,
    /// A flight through the scene, corner to corner over its center at a third of its height
    Fly,
}

pub fn run(scene: &SceneArg, kind: PathKind, frames: usize, out: &Path) -> Result<()> {
    super::common::check_outputs(&[], &[out])?;
    let loaded = super::load_scene(scene)?;
    let bounds = loaded.scene.world_aabb();
    let keys = match kind {
        PathKind::Street | PathKind::Aerial => loaded.path(matches!(kind, PathKind::Street), frames)?,
        PathKind::Orbit => sightline::scene::path::orbit_path(&bounds, frames)?,
        PathKind::Fly => sightline::scene::path::fly_path(&bounds, frames)?,
    };
    sightline::scene::path::write_path(out, &keys)?;
    println!("wrote {} frames to {}", keys.len(), out.display());
    Ok(())
}

pub fn export_obj(scene: &SceneArg, out: &Path) -> Result<()> {
    super::common::check_outputs(&[], &[out])?;
    let loaded = super::load_scene(scene)?;
    sightline::scene::export::export_obj(&loaded.scene, out)
        .with_context(|| format!("exporting to {}", out.display()))?;
    let s = loaded.scene.stats();
    println!("wrote {} triangles to {}", s.triangles, out.display());
    Ok(())
}

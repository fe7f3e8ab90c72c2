//! The visibility lab: hidden-surface algorithms other than the z-buffer, each drawing the
//! same view into the same [`Framebuffer`](crate::Framebuffer) so they can be compared
//! pixel for pixel.
//!
//! Sutherland, Sproull & Schumacker ("A Characterization of Ten Hidden-Surface Algorithms",
//! 1974) sorted the classic methods by where they sort: in object space (the painter's
//! depth sort of Newell, Newell & Sancha 1972; the BSP tree of Fuchs, Kedem & Naylor 1980),
//! in image space (Warnock's area subdivision, 1969; the z-buffer of Catmull, 1974), or
//! both. The lab runs them side by side on one input, the scene flattened to world-space
//! triangles in the engine's triangle-ID order ([`Soup`]), with the z-buffer as referee.
//!
//! Every method follows one contract:
//! - it takes a [`Soup`], a [`Camera`](sightline_scene::Camera) and a
//!   [`Framebuffer`](crate::Framebuffer), and writes `fb.ids` (0 = background, else 1 + the
//!   triangle's index in the soup, the ID the rasterizer writes)
//!   and, where it knows it, `fb.depth` (window depth of the visible surface at the pixel
//!   centre, 1.0 where empty); colour is left to [`crate::shade_pass`], which shades from the
//!   IDs, so images differ only where visibility differs;
//! - coverage is decided at pixel centres with the engine's fill rule, so a method that is
//!   right agrees with the z-buffer everywhere but on ties;
//! - it returns [`Counters`] that say what the algorithm did (comparisons, splits, windows, …);
//! - a method whose cost grows faster than the triangle count refuses a soup larger than
//!   its limit with [`Error::TooLarge`] instead of running for an hour.
//!
//! The methods here: [`painter`] (depth sort with the Newell–Newell–Sancha tests, and the
//! plain centroid sort beside it), [`bsp`] (the autopartition walked back to front, or
//! front to back with a coverage mask) and [`warnock`] (area subdivision). The first two
//! scan-convert through `scan`, which hands out the rasterizer's own pixels for a triangle
//! or a piece of one; Warnock's decides windows from the set-up triangles' edge functions.

pub mod bsp;
pub mod painter;
pub(crate) mod polygon;
pub(crate) mod scan;

pub use bsp::{BspMode, BspRenderer};

pub mod warnock;

use glam::Vec3;
use sightline_scene::Scene;

use crate::{Error, Result};

/// The scene flattened to world-space triangles, in triangle-ID order: triangle `i` is the
/// one whose ID is `i + 1` in every renderer of the engine.
#[derive(Debug, Clone, Default)]
pub struct Soup {
    triangles: Vec<[Vec3; 3]>,
}

impl Soup {
    /// Flattens `scene` as of its last transform update.
    ///
    /// Fails with [`Error::NotPropagated`] when the scene has edits not yet propagated
    /// (the triangles would not be the ones the other renderers see).
    pub fn from_scene(scene: &Scene) -> Result<Soup> {
        if scene.needs_update() {
            return Err(Error::NotPropagated);
        }
        crate::error::check_drawable(scene)?;
        let instances = scene.instances();
        let total: usize = instances.iter().map(|i| i.triangle_count as usize).sum();
        let mut triangles = Vec::with_capacity(total);
        for inst in &instances {
            let Some(mesh) = scene.mesh(inst.mesh) else { continue };
            let pos = mesh.positions();
            let world = |i: u32| inst.world_from_local.transform_point3(pos[i as usize]);
            for t in mesh.indices().chunks_exact(3) {
                triangles.push([world(t[0]), world(t[1]), world(t[2])]);
            }
        }
        Ok(Soup { triangles })
    }

    /// A soup of the given world-space triangles (tests and generated scenes).
    pub fn from_triangles(triangles: Vec<[Vec3; 3]>) -> Soup {
        Soup { triangles }
    }

    /// The triangles, in ID order.
    pub fn triangles(&self) -> &[[Vec3; 3]] {
        &self.triangles
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether the soup has no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The ID triangle `index` writes (1 + its index; 0 is background).
    pub fn id(index: usize) -> u32 {
        index as u32 + 1
    }

    /// Refuses a soup larger than `limit` for `method`, naming both.
    pub fn check_size(&self, method: &'static str, limit: usize) -> Result<()> {
        if self.len() > limit {
            return Err(Error::TooLarge { method, triangles: self.len(), limit });
        }
        Ok(())
    }
}

/// What a method did, as named counts in the order the method reports them.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Counters {
    entries: Vec<(&'static str, u64)>,
}

impl Counters {
    /// No counts.
    pub fn new() -> Counters {
        Counters::default()
    }

    /// Adds `n` to the count `name` (created at zero the first time).
    pub fn add(&mut self, name: &'static str, n: u64) {
        match self.entries.iter_mut().find(|(k, _)| *k == name) {
            Some((_, v)) => *v += n,
            None => self.entries.push((name, n)),
        }
    }

    /// The count `name`, if the method reported it.
    pub fn get(&self, name: &str) -> Option<u64> {
        self.entries.iter().find(|(k, _)| *k == name).map(|&(_, v)| v)
    }

    /// Every count, in the order first added.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, u64)> + '_ {
        self.entries.iter().copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counters_accumulate_in_first_added_order() {
        let mut c = Counters::new();
        c.add("splits", 2);
        c.add("comparisons", 5);
        c.add("splits", 3);
        assert_eq!(c.iter().collect::<Vec<_>>(), vec![("splits", 5), ("comparisons", 5)]);
        assert_eq!(c.get("missing"), None);
    }

    #[test]
    fn oversized_soups_are_refused_by_name() {
        let soup = Soup::from_triangles(vec![[Vec3::ZERO, Vec3::X, Vec3::Y]; 3]);
        let err = soup.check_size("warnock", 2).unwrap_err().to_string();
        assert!(err.contains("warnock") && err.contains('3') && err.contains('2'), "{err}");
        assert!(soup.check_size("warnock", 3).is_ok());
    }
}

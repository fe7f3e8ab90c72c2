//! Constructive solid geometry by ray casting (Roth 1982, "Ray Casting for Modeling Solids").
//!
//! A [`Csg`] expression combines primitives ([`Shape`]: sphere, cube, cylinder, cone) with
//! union, intersection and difference, each node placed by an affine transform. Per ray,
//! every primitive yields its span [enter, exit] with the surface normals at both ends
//! ([`primitive`]), the inner nodes combine the sorted span lists ([`interval::combine`]),
//! and the first entry of the root's list at or after the ray's start is the visible surface.
//!
//! The scene crate has no CSG node type, so CSG solids live next to the scene: a
//! [`CsgObject`] is a compiled tree with a world transform and a base color, handed to the
//! ray caster (its `with_csg`), which draws it in the same image as the triangle meshes.
//! This module knows nothing of the ray caster: the caster uses it, not the other way round. Its pixels get IDs *above* the triangle range: object `k` writes
//! `scene_triangle_count + 1 + k`. The rasterizer does not draw CSG solids.
//!
//! ```
//! use glam::{Affine3A, Vec3};
//! use sightline_render::csg::{Csg, CsgObject};
//!
//! // A hollow ball: the ray from outside meets the outer shell at t = 5 − 2.
//! let hollow = Csg::sphere(Vec3::ZERO, 2.0).subtract(Csg::sphere(Vec3::ZERO, 1.0));
//! let object = CsgObject::new("hollow", &hollow, Affine3A::IDENTITY, [1.0; 4])?;
//! let hit = object.intersect(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z, 0.0, f32::INFINITY).unwrap();
//! assert!((hit.t - 3.0).abs() < 1e-6 && hit.normal.z > 0.99);
//! # Ok::<(), sightline_render::Error>(())
//! ```

pub mod interval;
pub mod primitive;
pub mod tree;

use glam::{Affine3A, DAffine3, DMat3, DVec3, Vec3};
use sightline_scene::Aabb;

pub use interval::{combine, Crossing, Op, Span};
pub use primitive::Shape;
pub use tree::{Csg, CsgScratch, CsgTree};

use crate::{Error, Result};

/// A visible point of a CSG solid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CsgHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Outward unit normal in world space (on cut surfaces: pointing out of the result).
    pub normal: Vec3,
}

/// A compiled CSG solid placed in the world, with a base color.
#[derive(Debug, Clone)]
pub struct CsgObject {
    /// A name for messages.
    pub name: String,
    /// Base color (linear RGBA), used like a material's base color.
    pub color: [f32; 4],
    tree: CsgTree,
    object_from_world: DAffine3,
    normal_to_world: DMat3,
    bounds: Aabb,
}

fn to_f64(m: &Affine3A) -> DAffine3 {
    DAffine3::from_cols(
        m.matrix3.x_axis.as_dvec3(),
        m.matrix3.y_axis.as_dvec3(),
        m.matrix3.z_axis.as_dvec3(),
        m.translation.as_dvec3(),
    )
}

fn invalid(name: &str, why: String) -> Error {
    Error::Scene(sightline_scene::Error::InvalidTransform { what: format!("CSG object '{name}'"), why })
}

impl CsgObject {
    /// Compiles `csg` and places it with `world_from_object`. Errors on singular or
    /// non-finite transforms (of the object or of any node).
    pub fn new(name: impl Into<String>, csg: &Csg, world_from_object: Affine3A, color: [f32; 4]) -> Result<Self> {
        let name = name.into();
        let tree = csg.compile().map_err(|why| invalid(&name, why))?;
        let m = to_f64(&world_from_object);
        let det = m.matrix3.determinant();
        if !(det.is_finite() && det.abs() > 1e-300 && m.translation.is_finite()) {
            return Err(invalid(&name, "world transform is singular or not finite".into()));
        }
        let inv = m.inverse();
        let (lo, hi) = tree.bounds();
        let bounds = if lo.cmple(hi).all() {
            let c = m.transform_point3((lo + hi) * 0.5);
            let h = (hi - lo) * 0.5;
            let e = m.matrix3.x_axis.abs() * h.x + m.matrix3.y_axis.abs() * h.y + m.matrix3.z_axis.abs() * h.z;
            let pad = e * 1e-9 + 1e-9;
            Aabb::new((c - e - pad).as_vec3(), (c + e + pad).as_vec3())
        } else {
            Aabb::EMPTY
        };
        Ok(Self { name, color, tree, object_from_world: inv, normal_to_world: inv.matrix3.transpose(), bounds })
    }

    /// World-space bounds (empty when the solid is provably empty).
    pub fn world_bounds(&self) -> Aabb {
        self.bounds
    }

    /// The compiled tree.
    pub fn tree(&self) -> &CsgTree {
        &self.tree
    }

    /// The first surface point of the solid on `origin + t·dir` with `t` in `[t_min, t_max)`.
    pub fn intersect(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<CsgHit> {
        self.intersect_with(origin, dir, t_min, t_max, &mut CsgScratch::default())
    }

    /// [`CsgObject::intersect`] with caller-owned scratch buffers (no allocation once grown).
    pub fn intersect_with(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
        scratch: &mut CsgScratch,
    ) -> Option<CsgHit> {
        if !origin.is_finite() || !dir.is_finite() || dir == Vec3::ZERO || t_min.is_nan() {
            return None;
        }
        let (o, d) = (origin.as_dvec3(), dir.as_dvec3());
        let (t0, t1) = (t_min as f64, t_max as f64);
        // World bounds first.
        let (lo, hi) = (self.bounds.min.as_dvec3(), self.bounds.max.as_dvec3());
        let (mut near, mut far) = (t0, t1);
        for a in 0..3 {
            if d[a] == 0.0 {
                if o[a] < lo[a] || o[a] > hi[a] {
                    return None;
                }
                continue;
            }
            let (u, v) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
            near = near.max(u.min(v));
            far = far.min(u.max(v));
        }
        if near.is_nan() || far.is_nan() || near > far {
            return None;
        }
        let lo_ = self.object_from_world.transform_point3(o);
        let ld = self.object_from_world.transform_vector3(d);
        let spans = self.tree.spans(lo_, ld, scratch);
        let s = spans.iter().find(|s| s.enter.t >= t0 && s.enter.t.is_finite())?;
        if s.enter.t >= t1 {
            return None;
        }
        let n = (self.normal_to_world * s.enter.normal).normalize_or_zero();
        Some(CsgHit {
            t: s.enter.t as f32,
            normal: if n == DVec3::ZERO { -dir.normalize_or_zero() } else { n.as_vec3() },
        })
    }
}

/// The classic CSG example: a cube intersected with a sphere, minus three cylinders along
/// the axes (the picture on Wikipedia's CSG page), inside [−1, 1]³. The command line's
/// `sightline csg` draws it.
pub fn classic_demo() -> Csg {
    let cube = Csg::cuboid(Vec3::splat(-1.0), Vec3::splat(1.0));
    let sphere = Csg::sphere(Vec3::ZERO, 1.35);
    let r = 0.55;
    let cyl = |axis: Vec3| Csg::cylinder(-axis * 1.5, axis * 1.5, r);
    let holes = cyl(Vec3::X).union(cyl(Vec3::Y)).union(cyl(Vec3::Z));
    cube.intersect(sphere).subtract(holes)
}

//! Scatter: one mesh instanced many times with random translation, rotation and scale inside
//! a region (a forest of one tree, a crowd of one statue).

use glam::{Quat, Vec3};

use crate::rng::Rng;
use crate::{Aabb, Error, MeshId, NodeDesc, NodeId, Result, Scene, Transform};

/// Parameters of [`scatter`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScatterParams {
    /// Number of instances.
    pub count: u32,
    /// Region the instance origins are drawn from (uniformly).
    pub region: Aabb,
    /// Uniform scale range.
    pub scale: (f32, f32),
    /// Rotate about +y only (trees, statues) instead of uniformly in 3D.
    pub upright: bool,
    /// Random seed.
    pub seed: u64,
}

/// Adds `params.count` instances of `mesh` under a new group node `name` (under `parent` or
/// as a root); returns the group. Call [`Scene::update_transforms`] afterwards.
pub fn scatter(
    scene: &mut Scene,
    parent: Option<NodeId>,
    name: &str,
    mesh: MeshId,
    params: &ScatterParams,
) -> Result<NodeId> {
    scene.try_mesh(mesh)?;
    let (lo, hi) = params.scale;
    let scale_ok = lo > 0.0 && lo <= hi && hi.is_finite();
    if !params.region.is_finite() || !scale_ok {
        return Err(Error::InvalidParams(format!(
            "scatter '{name}' needs a finite region and 0 < min scale ≤ max scale, got {params:?}"
        )));
    }
    let group = scene.add_node(parent, NodeDesc::new(name))?;
    let mut rng = Rng::new(params.seed);
    let (lo, hi) = (params.region.min, params.region.max);
    for i in 0..params.count {
        let p = Vec3::new(rng.range(lo.x, hi.x), rng.range(lo.y, hi.y), rng.range(lo.z, hi.z));
        let rotation = if params.upright {
            Quat::from_rotation_y(rng.range(0.0, std::f32::consts::TAU))
        } else {
            // Shoemake's uniform random rotation.
            let (u1, u2, u3) =
                (rng.f32(), rng.range(0.0, std::f32::consts::TAU), rng.range(0.0, std::f32::consts::TAU));
            let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
            Quat::from_xyzw(a * u2.sin(), a * u2.cos(), b * u3.sin(), b * u3.cos())
        };
        let s = rng.range(params.scale.0, params.scale.1);
        let t = Transform { translation: p, rotation, scale: Vec3::splat(s) };
        scene.add_node(Some(group), NodeDesc::new(format!("{name} {i}")).transform(t).mesh(mesh))?;
    }
    Ok(group)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::cube;

    #[test]
    fn scatter_instances_share_the_mesh() {
        let mut s = Scene::new();
        let m = s.add_mesh(cube("c").unwrap());
        let region = Aabb::new(Vec3::splat(-10.0), Vec3::splat(10.0));
        let params = ScatterParams { count: 100, region, scale: (0.5, 2.0), upright: false, seed: 3 };
        scatter(&mut s, None, "crowd", m, &params).unwrap();
        s.update_transforms();
        let st = s.stats();
        assert_eq!((st.instances, st.meshes, st.triangles), (100, 1, 1200));
        for i in s.instances() {
            assert!(region.contains_point(i.world_from_local.translation.into()));
        }
        let bad = ScatterParams { scale: (0.0, 1.0), ..params };
        assert!(scatter(&mut s, None, "bad", m, &bad).is_err());
    }
}

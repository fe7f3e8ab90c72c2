//! The boxfield: the occlusion benchmark of record.
//!
//! 83,334 axis-aligned boxes (12 triangles each: 1,000,008 triangles), x and z uniform in
//! [−100, 100], resting on y = 0, half extents in x and z uniform in [0.1, 0.5], height
//! uniform in [0.5, 3.0]. In the default layout ([`BoxfieldLayout::Instanced`]) every box is
//! an instance of one unit cube (scaled and moved), so the vertex data is one cube's 24
//! vertices whatever the count; [`BoxfieldLayout::OneMesh`] stores every box in one
//! world-space mesh.

use glam::Vec3;

use crate::rng::Rng;
use crate::shapes::cube;
use crate::{Aabb, Error, Material, Mesh, NodeDesc, Result, Scene, Transform};

/// Parameters of [`boxfield`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxfieldParams {
    /// Number of boxes.
    pub boxes: u32,
    /// Half size of the square field.
    pub half_size: f32,
    /// Random seed.
    pub seed: u64,
    /// How the boxes are stored; the boxes, triangle order and IDs are the same either way.
    pub layout: BoxfieldLayout,
}

/// How [`boxfield`] stores its boxes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BoxfieldLayout {
    /// One node per box, all instancing one unit cube (the scene-graph way).
    #[default]
    Instanced,
    /// One node with one mesh of every box in world space: the flat triangle list an
    /// occlusion-culling library like Masked Occlusion Culling takes. Culling then works on
    /// clusters of nearby faces of one facing instead of on single boxes.
    OneMesh,
}

impl Default for BoxfieldParams {
    fn default() -> Self {
        Self { boxes: 83_334, half_size: 100.0, seed: 1993, layout: BoxfieldLayout::Instanced }
    }
}

/// Draws one box of the benchmark's size distribution centered at (x, z) on the ground.
fn random_box(rng: &mut Rng, x: f32, z: f32) -> Aabb {
    let hx = rng.range(0.1, 0.5);
    let hz = rng.range(0.1, 0.5);
    let h = rng.range(0.5, 3.0);
    Aabb::new(Vec3::new(x - hx, 0.0, z - hz), Vec3::new(x + hx, h, z + hz))
}

/// Builds the boxfield (world transforms propagated).
pub fn boxfield(params: &BoxfieldParams) -> Result<Scene> {
    if params.boxes == 0 || !(params.half_size > 0.0 && params.half_size.is_finite()) {
        return Err(Error::InvalidParams(format!("boxfield needs boxes > 0 and a positive size, got {params:?}")));
    }
    let mut scene = Scene::new();
    let cube = cube("box")?;
    let mat = scene.add_material(Material::color("box", [0.75, 0.7, 0.62]));
    let root = scene.add_node(None, NodeDesc::new("boxfield").material(mat))?;
    let mut rng = Rng::new(params.seed);
    let s = params.half_size;
    let boxes = (0..params.boxes).map(|_| {
        let (x, z) = (rng.range(-s, s), rng.range(-s, s));
        random_box(&mut rng, x, z)
    });
    match params.layout {
        BoxfieldLayout::Instanced => {
            let unit = scene.add_mesh(cube);
            for (i, b) in boxes.enumerate() {
                let t = Transform::from_translation(b.center()).with_scale(b.extent());
                scene.add_node(Some(root), NodeDesc::new(format!("box {i}")).transform(t).mesh(unit))?;
            }
        }
        BoxfieldLayout::OneMesh => {
            let n = params.boxes as usize;
            let (cp, ci) = (cube.positions(), cube.indices());
            let mut positions = Vec::with_capacity(n * cp.len());
            let mut indices = Vec::with_capacity(n * ci.len());
            for b in boxes {
                let first = positions.len() as u32;
                // The instanced layout's transform, applied here: the same world positions.
                let t = Transform::from_translation(b.center()).with_scale(b.extent()).to_affine("box")?;
                positions.extend(cp.iter().map(|&p| t.transform_point3(p)));
                indices.extend(ci.iter().map(|&i| first + i));
            }
            let mesh = scene.add_mesh(Mesh::new("boxes", positions, None, None, indices)?);
            scene.add_node(Some(root), NodeDesc::new("boxes").mesh(mesh))?;
        }
    }
    scene.update_transforms();
    Ok(scene)
}

/// The benchmark's query boxes: `count` boxes of the same size distribution, placed
/// uniformly (by area) in the horizontal view wedge of a camera at the origin looking
/// along +z with vertical field of view `fovy` and `aspect`, from 2 to 100 units ahead.
pub fn boxfield_queries(count: usize, fovy: f32, aspect: f32, seed: u64) -> Vec<Aabb> {
    let mut rng = Rng::new(seed ^ 0x9E37);
    let half = ((fovy * 0.5).tan() * aspect).atan();
    (0..count)
        .map(|_| {
            let r = rng.range(4.0, 10_000.0).sqrt();
            let a = rng.range(-half, half);
            random_box(&mut rng, r * a.sin(), r * a.cos())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_boxfield_follows_the_distribution() {
        let s = boxfield(&BoxfieldParams { boxes: 500, ..Default::default() }).unwrap();
        let st = s.stats();
        assert_eq!((st.instances, st.triangles, st.unique_triangles), (500, 6000, 12));
        for i in s.instances() {
            let b = i.world_aabb;
            let e = b.extent();
            assert!(b.min.y.abs() < 1e-5 && (0.5..=3.0).contains(&e.y), "{b:?}");
            assert!((0.2..=1.0).contains(&e.x) && (0.2..=1.0).contains(&e.z), "{b:?}");
            assert!(b.center().x.abs() <= 100.0 && b.center().z.abs() <= 100.0);
        }
    }

    #[test]
    fn both_layouts_hold_the_same_triangles() {
        let p = BoxfieldParams { boxes: 300, ..Default::default() };
        let a = boxfield(&p).unwrap();
        let b = boxfield(&BoxfieldParams { layout: BoxfieldLayout::OneMesh, ..p }).unwrap();
        let flat = |s: &Scene| -> Vec<[Vec3; 3]> {
            s.instances()
                .iter()
                .flat_map(|i| {
                    let m = s.mesh(i.mesh).unwrap();
                    (0..m.triangle_count()).map(move |t| {
                        m.triangle(t).map(|v| i.world_from_local.transform_point3(m.positions()[v as usize]))
                    })
                })
                .collect()
        };
        let (ta, tb) = (flat(&a), flat(&b));
        assert_eq!(ta.len(), 3600);
        assert_eq!(ta, tb);
        assert_eq!(b.stats().instances, 1);
    }

    #[test]
    fn default_has_the_benchmark_triangle_count() {
        assert_eq!(BoxfieldParams::default().boxes as u64 * 12, 1_000_008);
    }

    #[test]
    fn queries_lie_in_the_wedge() {
        for b in boxfield_queries(1000, 60f32.to_radians(), 16.0 / 9.0, 1) {
            let c = b.center();
            let r = (c.x * c.x + c.z * c.z).sqrt();
            assert!((1.9..=100.1).contains(&r) && c.z > 0.0, "{c}");
        }
    }
}

//! The procedural city: blocks on a street grid, box buildings whose facades show windows,
//! a ground split into tiles.
//!
//! Layout: street center lines run along x = k·P and z = k·P (pitch P = 52, street width 12,
//! k = 0..=blocks), shifted so the city is centered on the origin. Each 40 × 40 block holds
//! 2 × 2 lots; each lot one building with a footprint of at most 18 × 18 set back from the
//! street. Buildings are drawn from a table of prototypes (footprint, height), rotated by a
//! multiple of 90°, so repeated shapes share meshes (instancing). Facades are grids of
//! cells whose count is chosen so the whole city has the requested triangle count; the
//! cells are laid out as piers, spandrels and window panes ([`super::facade`]), and each
//! building is a node with up to three children: its walls, its dark panes and its lit
//! panes, each with its own mesh and material. Blocks are group nodes carrying a wall
//! material that their buildings inherit (the towers override it).

use glam::{Quat, Vec3};

use super::facade::facade;
use crate::rng::Rng;
use crate::shapes::ground_quad;
use crate::{Aabb, Error, Material, NodeDesc, Result, Scene, Transform};

/// Distance between street center lines.
pub const PITCH: f32 = 52.0;
/// Width of a street.
pub const STREET: f32 = 12.0;
const LOT: f32 = (PITCH - STREET) / 2.0;
/// The share of window panes that are lit.
const LIT_SHARE: f32 = 0.2;

/// Parameters of [`city`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CityParams {
    /// Blocks per side (blocks² blocks, 4 buildings each).
    pub blocks: u32,
    /// Facade subdivision: grid cells per unit of length across a facade (0.7× that up it).
    pub subdivision: f32,
    /// Number of distinct building shapes (meshes).
    pub prototypes: u32,
    /// Random seed: same seed, same city, bit for bit.
    pub seed: u64,
}

impl Default for CityParams {
    fn default() -> Self {
        Self::for_triangles(1_000_000)
    }
}

#[derive(Debug, Clone, Copy)]
struct Prototype {
    size: Vec3,
}

impl Prototype {
    fn cells(&self, subdivision: f32) -> [u32; 3] {
        // Floors are taller than windows are wide.
        let c = |len: f32, k: f32| ((len * subdivision * k).round() as u32).max(1);
        [c(self.size.x, 1.0), c(self.size.y, 0.7), c(self.size.z, 1.0)]
    }
    fn triangles(&self, subdivision: f32) -> u64 {
        let [x, y, z] = self.cells(subdivision).map(u64::from);
        2 * (2 * x * y + 2 * z * y + x * z)
    }
}

/// Where the streets are: what the camera paths need to stay out of buildings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CityLayout {
    /// Blocks per side.
    pub blocks: u32,
    /// World x (and z) of street line 0.
    pub origin: f32,
    /// Tallest building.
    pub max_height: f32,
}

impl CityLayout {
    /// World coordinate of street center line `k` (0..=blocks).
    pub fn street(&self, k: u32) -> f32 {
        self.origin + k as f32 * PITCH
    }
    /// The xz-extent of the city (ground included).
    pub fn bounds(&self) -> Aabb {
        let lo = self.origin - PITCH * 0.5;
        let hi = self.street(self.blocks) + PITCH * 0.5;
        Aabb::new(Vec3::new(lo, 0.0, lo), Vec3::new(hi, self.max_height, hi))
    }
}

/// A built city: the scene and its street layout.
#[derive(Debug, Clone)]
pub struct City {
    /// The scene, world transforms propagated.
    pub scene: Scene,
    /// The street grid.
    pub layout: CityLayout,
}

fn prototypes(params: &CityParams) -> Vec<Prototype> {
    let mut rng = Rng::new(params.seed ^ 0xC17);
    (0..params.prototypes.max(1))
        .map(|_| {
            let w = 12.0 + 2.0 * rng.below(4) as f32;
            let d = 12.0 + 2.0 * rng.below(4) as f32;
            // Mostly mid-rise, some towers.
            let h = if rng.f32() < 0.15 { rng.range(45.0, 80.0) } else { rng.range(9.0, 40.0) };
            Prototype { size: Vec3::new(w, (h / 3.0).round() * 3.0, d) }
        })
        .collect()
}

/// For each building: (prototype index, quarter turns, offset inside the lot), in node order.
fn placements(params: &CityParams, protos: &[Prototype]) -> Vec<(usize, u32, [f32; 2])> {
    let mut rng = Rng::new(params.seed);
    let n = (params.blocks * params.blocks * 4) as usize;
    (0..n)
        .map(|_| {
            let p = rng.below(protos.len() as u32) as usize;
            let turns = rng.below(4);
            let s = protos[p].size;
            let (w, d) = if turns % 2 == 1 { (s.z, s.x) } else { (s.x, s.z) };
            // Keep at least 1 unit between the building and the lot edge.
            let jx = rng.range(-1.0, 1.0) * ((LOT - w) * 0.5 - 1.0).max(0.0);
            let jz = rng.range(-1.0, 1.0) * ((LOT - d) * 0.5 - 1.0).max(0.0);
            (p, turns, [jx, jz])
        })
        .collect()
}

impl CityParams {
    /// Parameters whose city has at least `triangles` triangles (and not many more): the
    /// block count grows slowly with the target, the facade subdivision makes up the rest.
    pub fn for_triangles(triangles: u64) -> Self {
        let t = triangles.max(1000) as f64;
        let blocks = ((12.0 * (t / 1e6).powf(0.25)).round() as u32).clamp(2, 64);
        let mut p = CityParams { blocks, subdivision: 0.5, prototypes: 48, seed: 2026 };
        let (mut lo, mut hi) = (0.001f32, 64.0f32);
        for _ in 0..60 {
            p.subdivision = 0.5 * (lo + hi);
            if p.triangle_count() >= triangles {
                hi = p.subdivision;
            } else {
                lo = p.subdivision;
            }
        }
        p.subdivision = hi;
        p
    }

    /// The number of triangles the city will have (buildings and ground), without building it.
    pub fn triangle_count(&self) -> u64 {
        let protos = prototypes(self);
        let per: Vec<u64> = protos.iter().map(|p| p.triangles(self.subdivision)).collect();
        let buildings: u64 = placements(self, &protos).iter().map(|b| per[b.0]).sum();
        buildings + 2 * (self.blocks as u64 + 1).pow(2)
    }

    fn validate(&self) -> Result<()> {
        if self.blocks == 0 || self.blocks > 256 {
            return Err(Error::InvalidParams(format!("city blocks per side {} is not in 1..=256", self.blocks)));
        }
        if !(self.subdivision > 0.0 && self.subdivision <= 64.0) {
            return Err(Error::InvalidParams(format!("facade subdivision {} is not in (0, 64]", self.subdivision)));
        }
        if self.prototypes == 0 {
            return Err(Error::InvalidParams("a city needs at least one building prototype".into()));
        }
        Ok(())
    }
}

/// Builds the city (world transforms already propagated).
pub fn city(params: &CityParams) -> Result<City> {
    params.validate()?;
    let protos = prototypes(params);
    let mut scene = Scene::new();
    // Per prototype: walls, dark panes, lit panes (a prototype may have no panes of a kind).
    let mut meshes = Vec::with_capacity(protos.len());
    for (i, p) in protos.iter().enumerate() {
        let h = p.size * Vec3::new(0.5, 0.0, 0.5);
        let seed = params.seed ^ (0x11_9475 + i as u64);
        let f = facade(&format!("building {i}"), -h, p.size - h, p.cells(params.subdivision), seed, LIT_SHARE)?;
        let mut add = |m: Option<crate::Mesh>| m.map(|m| scene.add_mesh(m));
        meshes.push([add(Some(f.walls)), add(f.windows), add(f.lit)]);
    }
    let ground_mesh = scene.add_mesh(ground_quad("ground tile", 1)?);
    let palette = [
        [0.72, 0.66, 0.58],
        [0.55, 0.60, 0.68],
        [0.78, 0.74, 0.70],
        [0.62, 0.52, 0.45],
        [0.48, 0.52, 0.50],
        [0.80, 0.70, 0.55],
    ];
    let mats: Vec<_> = palette
        .iter()
        .enumerate()
        .map(|(i, c)| scene.add_material(Material::color(format!("facade {i}"), *c)))
        .collect();
    let glass = scene.add_material(Material::color("glass tower", [0.35, 0.45, 0.60]));
    let panes = [
        None,
        Some(scene.add_material(Material::color("window", [0.10, 0.13, 0.20]))),
        Some(scene.add_material(Material::color("lit window", [0.35, 0.28, 0.15]).with_emissive([0.75, 0.55, 0.25]))),
    ];
    let asphalt = scene.add_material(Material::color("ground", [0.30, 0.30, 0.32]));

    let origin = -(params.blocks as f32) * PITCH * 0.5;
    let root = scene.add_node(None, NodeDesc::new("city"))?;
    let ground = scene.add_node(Some(root), NodeDesc::new("ground").material(asphalt))?;
    for k in 0..=params.blocks {
        for i in 0..=params.blocks {
            let t = Transform::from_translation(Vec3::new(origin + i as f32 * PITCH, 0.0, origin + k as f32 * PITCH))
                .with_scale(Vec3::new(PITCH, 1.0, PITCH));
            scene.add_node(Some(ground), NodeDesc::new(format!("ground {i},{k}")).transform(t).mesh(ground_mesh))?;
        }
    }
    let buildings = scene.add_node(Some(root), NodeDesc::new("buildings"))?;
    let place = placements(params, &protos);
    let mut rng = Rng::new(params.seed ^ 0xB10C);
    let mut max_height = 0f32;
    let mut next = place.iter();
    for bz in 0..params.blocks {
        for bx in 0..params.blocks {
            // Block center: between street lines bx and bx + 1.
            let center = Vec3::new(origin + (bx as f32 + 0.5) * PITCH, 0.0, origin + (bz as f32 + 0.5) * PITCH);
            let mat = mats[rng.below(mats.len() as u32) as usize];
            let block = scene.add_node(
                Some(buildings),
                NodeDesc::new(format!("block {bx},{bz}")).transform(Transform::from_translation(center)).material(mat),
            )?;
            for lot in 0..4u32 {
                let Some(&(p, turns, [jx, jz])) = next.next() else {
                    break;
                };
                let lx = (lot % 2) as f32 * LOT - LOT * 0.5 + jx;
                let lz = (lot / 2) as f32 * LOT - LOT * 0.5 + jz;
                let t = Transform::from_translation(Vec3::new(lx, 0.0, lz))
                    .with_rotation(Quat::from_rotation_y(turns as f32 * std::f32::consts::FRAC_PI_2));
                let mut desc = NodeDesc::new(format!("building {bx},{bz},{lot}")).transform(t);
                if protos[p].size.y > 44.0 {
                    desc = desc.material(glass);
                }
                let building = scene.add_node(Some(block), desc)?;
                for ((mesh, part), mat) in meshes[p].iter().zip(["walls", "windows", "lit windows"]).zip(panes) {
                    if let Some(mesh) = *mesh {
                        let mut d = NodeDesc::new(part).mesh(mesh);
                        if let Some(m) = mat {
                            d = d.material(m);
                        }
                        scene.add_node(Some(building), d)?;
                    }
                }
                max_height = max_height.max(protos[p].size.y);
            }
        }
    }
    scene.update_transforms();
    Ok(City { scene, layout: CityLayout { blocks: params.blocks, origin, max_height } })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn predicted_count_matches_and_target_is_reached() {
        for target in [20_000u64, 300_000] {
            let p = CityParams::for_triangles(target);
            let c = city(&p).unwrap();
            let s = c.scene.stats();
            assert_eq!(s.triangles, p.triangle_count());
            assert!(s.triangles >= target && s.triangles < target + target / 5, "{} for {target}", s.triangles);
            assert!(s.unique_triangles < s.triangles, "buildings must share meshes");
        }
    }

    #[test]
    fn same_seed_same_city() {
        let p = CityParams::for_triangles(30_000);
        let (a, b) = (city(&p).unwrap().scene, city(&p).unwrap().scene);
        let (ia, ib) = (a.instances(), b.instances());
        assert_eq!(ia.len(), ib.len());
        for (x, y) in ia.iter().zip(&ib) {
            assert_eq!(x.world_from_local, y.world_from_local);
            assert_eq!(a.mesh(x.mesh).unwrap().positions(), b.mesh(y.mesh).unwrap().positions());
        }
    }

    #[test]
    fn facades_have_dark_and_lit_windows_of_their_own_material() {
        let c = city(&CityParams::for_triangles(60_000)).unwrap();
        let s = &c.scene;
        let mut tris = std::collections::HashMap::<String, u64>::new();
        for inst in s.instances() {
            let name = s.instance_material(&inst).name.clone();
            *tris.entry(name).or_default() += u64::from(inst.triangle_count);
        }
        let (dark, lit) = (tris["window"], tris["lit window"]);
        let all: u64 = tris.values().sum();
        // Panes are a good part of the facades; about a fifth of them are lit.
        assert!(dark + lit > all / 10 && dark + lit < all * 3 / 4, "{dark} + {lit} pane triangles of {all}");
        assert!(lit * 10 > dark && lit < dark, "{lit} lit vs {dark} dark");
        let lit_mat = s.materials().find(|(_, m)| m.name == "lit window").unwrap().1;
        assert!(lit_mat.emissive.iter().all(|&e| e > 0.0), "lit windows give off light");
        assert!(tris.keys().any(|k| k.starts_with("facade")), "walls keep their block's material");
    }

    #[test]
    fn buildings_stay_off_the_streets() {
        let c = city(&CityParams::for_triangles(50_000)).unwrap();
        let l = c.layout;
        for inst in c.scene.instances() {
            let b = inst.world_aabb;
            if b.max.y <= 0.0 {
                continue; // ground
            }
            for k in 0..=l.blocks {
                let s = l.street(k);
                for (lo, hi) in [(b.min.x, b.max.x), (b.min.z, b.max.z)] {
                    assert!(hi < s - STREET * 0.5 || lo > s + STREET * 0.5, "building {b:?} on street {k}");
                }
            }
        }
    }
}

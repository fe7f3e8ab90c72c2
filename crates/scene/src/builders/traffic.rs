//! The city with traffic: the procedural [`city`] plus N vehicles driving along its streets
//! and tower cranes (see the `crane` module), all moving by [`Animation`]s — the moving
//! benchmark scene `city+traffic:N`.
//!
//! Routes. Each vehicle drives round a rectangle of streets (1–3 blocks a side, chosen from
//! the seed) in the right-hand lane: the lane is the street center line moved 3 units to the
//! driver's right (`right = (−d.z, d.x)` for a heading `d` in the xz-plane), so the loop's
//! corners sit 3 units off the intersection centers, inside the 12-wide streets. Each corner
//! is cut by a chamfer from 4 units before it to 4 units after it, so a vehicle turns over
//! the chamfer instead of pivoting on the spot. The route is a closed polyline of
//! 2 × 4 vertices; at each vertex the heading is that of the straight street before
//! (chamfer entry) or after (chamfer exit).
//!
//! Keys. A vehicle drives at a constant speed (8–14 units/s) from a random point of its loop;
//! its translation keys are the loop's vertices at the times it reaches them, LINEAR, and its
//! rotation keys the headings at the same times, LINEAR (slerp turns the vehicle through 90°
//! along each chamfer and holds it on the straights). The first and last keys are the start
//! point, one lap apart, so the animation loops seamlessly ([`Wrap::Loop`]).
//!
//! Clearance (checked by the tests): lanes are 3 units from the center line and vehicles at
//! most about 2.7 wide (wheels and the ±3% size spread included), so they stay inside the 12-wide street; on a chamfer a vehicle of half-length
//! at most 5 stays inside the intersection's cross of streets; buildings keep 1 unit back from
//! the street. Vehicles on the same lane at different speeds may pass through one another:
//! this is a visibility benchmark, not a traffic simulation (each vehicle's height and width
//! vary by a few percent, so that two passing through one another never share a face plane).
//!
//! Vehicles are a few instanced meshes (car, van, bus, truck: body and cabin boxes, wheels),
//! each placed under a `traffic` root added after the city, so the city's triangle IDs are
//! those of the plain city.

use glam::{Quat, Vec2, Vec3};

use super::city::City;
use super::city::{city, CityLayout, CityParams, PITCH};
use super::crane::{add_crane, jib_height, CraneMeshes, REACH};
use crate::animation::{Animation, Curve, Interpolation, Sampler, Wrap};
use crate::rng::Rng;
use crate::shapes::MeshBuilder;
use crate::{Error, Material, MeshId, NodeDesc, Result, Scene, Transform};

/// Distance of a lane's center from the street's center line.
pub const LANE_OFFSET: f32 = 3.0;
/// How far before and after a corner a vehicle starts and ends its turn.
const CHAMFER: f32 = 4.0;
/// Most vehicles a traffic city accepts.
pub const MAX_VEHICLES: u32 = 1_000_000;

/// Parameters of [`city_with_traffic`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrafficParams {
    /// The city under the traffic.
    pub city: CityParams,
    /// Number of vehicles.
    pub vehicles: u32,
    /// Number of tower cranes (at least one for the benchmark scene).
    pub cranes: u32,
    /// Seed of routes, vehicle kinds, colors and cranes.
    pub seed: u64,
}

impl TrafficParams {
    /// The default city (10^6 triangles) with `vehicles` vehicles and one crane per 48 blocks
    /// (at least one).
    pub fn new(vehicles: u32) -> Self {
        let city = CityParams::default();
        Self { city, vehicles, cranes: (city.blocks * city.blocks / 48).max(1), seed: 2026 }
    }
}

/// The vehicle kinds: name, share of the traffic, boxes (min, max, faces split into cells),
/// wheels (x positions; on both sides). Vehicles face +x, origin at the ground center.
struct Kind {
    name: &'static str,
    share: f32,
    boxes: &'static [([f32; 3], [f32; 3])],
    wheels: &'static [f32],
    half_width: f32,
}

const KINDS: [Kind; 4] = [
    Kind {
        name: "car",
        share: 0.70,
        boxes: &[([-2.1, 0.35, -0.9], [2.1, 1.0, 0.9]), ([-1.2, 1.0, -0.8], [0.9, 1.5, 0.8])],
        wheels: &[-1.35, 1.35],
        half_width: 0.9,
    },
    Kind {
        name: "van",
        share: 0.15,
        boxes: &[([-2.5, 0.4, -1.0], [1.5, 2.3, 1.0]), ([1.5, 0.4, -1.0], [2.5, 1.3, 1.0])],
        wheels: &[-1.6, 1.6],
        half_width: 1.0,
    },
    Kind {
        name: "bus",
        share: 0.08,
        boxes: &[([-5.0, 0.45, -1.25], [5.0, 3.1, 1.25])],
        wheels: &[-3.4, -2.4, 3.4],
        half_width: 1.25,
    },
    Kind {
        name: "truck",
        share: 0.07,
        boxes: &[
            ([2.9, 0.5, -1.2], [5.0, 3.0, 1.2]),
            ([-5.0, 1.0, -1.25], [2.7, 3.6, 1.25]),
            ([-5.0, 0.5, -0.8], [5.0, 1.0, 0.8]),
        ],
        wheels: &[-4.0, -2.9, 3.8],
        half_width: 1.25,
    },
];

/// The mesh of one vehicle kind: its boxes (bottom faces left out: the road hides them)
/// and wheels as small boxes on both sides.
fn vehicle_mesh(kind: &Kind) -> Result<crate::Mesh> {
    let mut b = MeshBuilder::default();
    for &(min, max) in kind.boxes {
        b.add_box(Vec3::from(min), Vec3::from(max), [1, 1, 1], false);
    }
    for &x in kind.wheels {
        for side in [-1.0f32, 1.0] {
            let z = side * (kind.half_width - 0.1);
            b.add_box(Vec3::new(x - 0.38, 0.0, z - 0.14), Vec3::new(x + 0.38, 0.76, z + 0.14), [1, 1, 1], false);
        }
    }
    b.build(&format!("vehicle {}", kind.name))
}

/// A closed route: vertices with positions (xz) and headings, in driving order.
struct Route {
    points: Vec<Vec2>,
    headings: Vec<Quat>,
}

/// The rotation that turns a vehicle's +x towards the xz-direction `d`.
fn heading(d: Vec2) -> Quat {
    Quat::from_rotation_y((-d.y).atan2(d.x))
}

impl Route {
    /// The loop round the rectangle of street lines `[i0, i1] × [k0, k1]`, clockwise or not
    /// as seen from above, in the right-hand lane.
    fn rectangle(layout: &CityLayout, [i0, i1]: [u32; 2], [k0, k1]: [u32; 2], reverse: bool) -> Self {
        let mut corners =
            [[i0, k0], [i1, k0], [i1, k1], [i0, k1]].map(|[i, k]| Vec2::new(layout.street(i), layout.street(k)));
        if reverse {
            corners.reverse();
        }
        let mut points = Vec::with_capacity(8);
        let mut headings = Vec::with_capacity(8);
        for c in 0..4 {
            let (prev, at, next) = (corners[(c + 3) % 4], corners[c], corners[(c + 1) % 4]);
            let (d_in, d_out) = ((at - prev).normalize(), (next - at).normalize());
            let right = |d: Vec2| Vec2::new(-d.y, d.x);
            let corner = at + (right(d_in) + right(d_out)) * LANE_OFFSET;
            points.extend([corner - d_in * CHAMFER, corner + d_out * CHAMFER]);
            headings.extend([heading(d_in), heading(d_out)]);
        }
        Self { points, headings }
    }

    fn len(&self) -> usize {
        self.points.len()
    }

    /// Arc length from vertex 0 to each vertex, and the whole loop's length.
    fn arc_lengths(&self) -> (Vec<f32>, f32) {
        let mut s = Vec::with_capacity(self.len());
        let mut total = 0.0;
        for j in 0..self.len() {
            s.push(total);
            total += self.points[j].distance(self.points[(j + 1) % self.len()]);
        }
        (s, total)
    }

    /// The animation of one lap at `speed` from the point at arc length `start` (in
    /// `[0, length)`): translation and rotation samplers with the same key times.
    fn lap(&self, start: f32, speed: f32) -> Result<(Sampler<Vec3>, Sampler<Quat>)> {
        let (arc, total) = self.arc_lengths();
        let n = self.len();
        // The segment the start point lies on, and the pose there.
        let seg = arc.iter().rposition(|&a| a <= start).unwrap_or(0);
        let seg_len = arc.get(seg + 1).copied().unwrap_or(total) - arc[seg];
        let f = if seg_len > 0.0 { (start - arc[seg]) / seg_len } else { 0.0 };
        let next = (seg + 1) % n;
        let start_point = self.points[seg].lerp(self.points[next], f);
        let start_heading = crate::animation::slerp(self.headings[seg], self.headings[next], f);
        let mut times = vec![0.0];
        let mut points = vec![start_point];
        let mut rotations = vec![start_heading];
        for step in 1..=n {
            let j = (seg + step) % n;
            let mut s = arc[j] - start;
            if s <= 0.0 {
                s += total;
            }
            if s >= total {
                continue; // the start point itself (start exactly on a vertex)
            }
            times.push(s / speed);
            points.push(self.points[j]);
            rotations.push(self.headings[j]);
        }
        times.push(total / speed);
        points.push(start_point);
        rotations.push(start_heading);
        let to3 = |p: &Vec2| Vec3::new(p.x, 0.0, p.y);
        let bad = Error::InvalidParams;
        let t = Sampler::new(times.clone(), points.iter().map(to3).collect(), Interpolation::Linear).map_err(bad)?;
        let r = Sampler::new(times, rotations, Interpolation::Linear).map_err(bad)?;
        Ok((t, r))
    }
}

/// A random span of 1–3 consecutive street lines' gaps inside `0..=blocks`.
fn span(rng: &mut Rng, blocks: u32) -> [u32; 2] {
    let w = (1 + rng.below(3)).min(blocks);
    let lo = rng.below(blocks - w + 1);
    [lo, lo + w]
}

/// Builds the city with traffic and cranes; world transforms propagated at time 0 (which is
/// also what `scene.animate(0.0)` gives).
pub fn city_with_traffic(params: &TrafficParams) -> Result<City> {
    if params.vehicles > MAX_VEHICLES {
        return Err(Error::InvalidParams(format!("{} vehicles is more than {MAX_VEHICLES}", params.vehicles)));
    }
    let City { mut scene, layout } = city(&params.city)?;
    let blocks = layout.blocks;
    if params.cranes > blocks * blocks {
        return Err(Error::InvalidParams(format!("{} cranes do not fit in {} blocks", params.cranes, blocks * blocks)));
    }
    let mut rng = Rng::new(params.seed ^ 0x7AFF1C);
    add_cranes(&mut scene, &layout, params.cranes, &mut rng)?;

    let meshes: Vec<MeshId> =
        KINDS.iter().map(|k| vehicle_mesh(k).map(|m| scene.add_mesh(m))).collect::<Result<_>>()?;
    let paints = [
        ("red", [0.75, 0.12, 0.10]),
        ("blue", [0.15, 0.30, 0.70]),
        ("white", [0.90, 0.90, 0.88]),
        ("black", [0.10, 0.10, 0.12]),
        ("taxi yellow", [0.95, 0.78, 0.10]),
        ("green", [0.20, 0.50, 0.30]),
    ];
    let paints: Vec<_> =
        paints.iter().map(|(n, c)| scene.add_material(Material::color(format!("vehicle {n}"), *c))).collect();
    // Routes and keys first, nodes next, animations last: each vehicle's keys sit together
    // in memory, in the order `animate` visits them.
    let mut drives = Vec::with_capacity(params.vehicles as usize);
    for _ in 0..params.vehicles {
        let mut pick = rng.f32();
        let kind = KINDS.iter().position(|k| {
            pick -= k.share;
            pick < 0.0
        });
        let kind = kind.unwrap_or(0);
        let route = Route::rectangle(&layout, span(&mut rng, blocks), span(&mut rng, blocks), rng.below(2) == 1);
        let (_, length) = route.arc_lengths();
        let speed = rng.range(8.0, 14.0);
        let (t, r) = route.lap(rng.f32() * length, speed)?;
        let paint = paints[rng.below(paints.len() as u32) as usize];
        drives.push((kind, paint, t, r));
    }
    let traffic = scene.add_node(None, NodeDesc::new("traffic"))?;
    let mut nodes = Vec::with_capacity(drives.len());
    // Each vehicle is a little taller or lower and wider or narrower than its kind (±3%, about
    // its ground point): two vehicles of one kind driving through each other in one lane
    // would otherwise have coplanar sides and roofs, whose pixels rounding decides
    // differently in each renderer. Drawn from a generator of its own, so the routes are
    // those of the same seed without it.
    let mut sizes = Rng::new(params.seed ^ 0x51_2E5);
    for (v, (kind, paint, t, r)) in drives.iter().enumerate() {
        let size = Vec3::new(1.0, sizes.range(0.97, 1.03), sizes.range(0.97, 1.03));
        let start = Transform::from_translation(t.sample(0.0)).with_rotation(r.sample(0.0)).with_scale(size);
        let desc = NodeDesc::new(format!("{} {v}", KINDS[*kind].name)).transform(start);
        nodes.push(scene.add_node(Some(traffic), desc.mesh(meshes[*kind]).material(*paint))?);
    }
    for (v, ((_, _, t, r), node)) in drives.into_iter().zip(nodes).enumerate() {
        scene.add_animation(
            Animation::new(format!("vehicle {v}"))
                .with_wrap(Wrap::Loop)
                .with_channel(node, Curve::Translation(t))
                .with_channel(node, Curve::Rotation(r)),
        );
    }
    scene.update_transforms();
    Ok(City { scene, layout })
}

/// Adds `count` cranes at distinct block centers, each jib above the tallest building within
/// its reach.
fn add_cranes(scene: &mut Scene, layout: &CityLayout, count: u32, rng: &mut Rng) -> Result<()> {
    if count == 0 {
        return Ok(());
    }
    let buildings: Vec<_> =
        scene.instances().iter().map(|i| i.world_aabb).filter(|b| b.max.y > 0.0 && !b.is_empty()).collect();
    let meshes = CraneMeshes::add(scene)?;
    let root = scene.add_node(None, NodeDesc::new("cranes"))?;
    let blocks = layout.blocks;
    let mut used = Vec::new();
    for index in 0..count as usize {
        let mut b = rng.below(blocks * blocks);
        while used.contains(&b) {
            b = (b + 1) % (blocks * blocks);
        }
        used.push(b);
        let (bx, bz) = (b % blocks, b / blocks);
        let base = Vec3::new(layout.street(bx) + PITCH * 0.5, 0.0, layout.street(bz) + PITCH * 0.5);
        let tallest = buildings
            .iter()
            .filter(|a| {
                let nearest = Vec3::new(base.x.clamp(a.min.x, a.max.x), 0.0, base.z.clamp(a.min.z, a.max.z));
                nearest.distance(base) < REACH
            })
            .fold(0.0f32, |h, a| h.max(a.max.y));
        add_crane(scene, &meshes, root, index, base, jib_height(tallest), rng)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use glam::Vec3Swizzles;

    use super::super::city::STREET;
    use super::*;
    use crate::Aabb;

    fn small(vehicles: u32) -> TrafficParams {
        TrafficParams { city: CityParams::for_triangles(40_000), vehicles, cranes: 2, seed: 5 }
    }

    fn buildings(scene: &Scene) -> Vec<Aabb> {
        let (_, cranes) = named_roots(scene);
        scene
            .instances()
            .iter()
            .filter(|i| i.world_aabb.max.y > 0.0 && !is_under(scene, i.node, cranes) && !is_under(scene, i.node, None))
            .map(|i| i.world_aabb)
            .collect()
    }

    /// The `traffic` and `cranes` roots.
    fn named_roots(scene: &Scene) -> (Option<crate::NodeId>, Option<crate::NodeId>) {
        (scene.find("traffic"), scene.find("cranes"))
    }

    /// True when `id` is below `root` (`None`: below the `traffic` root).
    fn is_under(scene: &Scene, id: crate::NodeId, root: Option<crate::NodeId>) -> bool {
        let root = root.or_else(|| scene.find("traffic"));
        let mut cur = Some(id);
        while let Some(c) = cur {
            if Some(c) == root {
                return true;
            }
            cur = scene.node(c).and_then(|n| n.parent());
        }
        false
    }

    #[test]
    fn vehicle_meshes_are_small() {
        let tris: Vec<usize> = KINDS.iter().map(|k| vehicle_mesh(k).unwrap().triangle_count()).collect();
        // Boxes without bottoms (10 triangles each): car 2 + 4 wheels, van 2 + 4, bus 1 + 6,
        // truck 3 + 6.
        assert_eq!(tris, [60, 60, 70, 90]);
        assert!((KINDS.iter().map(|k| k.share).sum::<f32>() - 1.0).abs() < 1e-6);
    }

    /// Every footprint corner of every vehicle, at many times over a minute, is on a street
    /// (within half a street width of a center line, in x or in z) and in no building.
    #[test]
    fn vehicles_stay_on_the_streets() {
        let mut c = city_with_traffic(&small(300)).unwrap();
        let houses = buildings(&c.scene);
        assert!(houses.len() > 50);
        let l = c.layout;
        let on_street = |v: f32| (0..=l.blocks).any(|k| (v - l.street(k)).abs() <= STREET * 0.5);
        for step in 0..90 {
            let t = step as f32 * 0.71;
            c.scene.animate(t).unwrap();
            c.scene.update_transforms();
            let (traffic, _) = named_roots(&c.scene);
            let vehicles: Vec<_> = c.scene.node(traffic.unwrap()).unwrap().children().collect();
            assert_eq!(vehicles.len(), 300);
            for v in vehicles {
                let n = c.scene.node(v).unwrap();
                let mesh = c.scene.mesh(n.mesh().unwrap()).unwrap().aabb();
                for corner in mesh.corners().into_iter().filter(|p| p.y == mesh.min.y) {
                    let p = n.world_matrix().transform_point3(corner);
                    assert!(on_street(p.x) || on_street(p.z), "{} at t = {t}: corner {p} is off the street", n.name());
                    let p = Vec3::new(p.x, 0.5, p.z);
                    assert!(
                        !houses.iter().any(|h| h.contains_point(p)),
                        "{} at t = {t}: corner {p} in a building",
                        n.name()
                    );
                }
            }
        }
    }

    #[test]
    fn animate_moves_every_vehicle_and_laps_are_seamless() {
        let mut c = city_with_traffic(&small(50)).unwrap();
        let before: Vec<_> = c.scene.instances().iter().map(|i| i.world_from_local).collect();
        // Time 0 is the pose the builder set.
        c.scene.animate(0.0).unwrap();
        c.scene.update_transforms();
        for (a, b) in before.iter().zip(c.scene.instances()) {
            assert!(a.abs_diff_eq(b.world_from_local, 1e-4));
        }
        c.scene.animate(1.0).unwrap();
        c.scene.update_transforms();
        let moved =
            c.scene.instances().iter().zip(&before).filter(|(i, b)| !i.world_from_local.abs_diff_eq(**b, 1e-3)).count();
        // 50 vehicles and, per crane, jib, trolley, cable and hook.
        assert_eq!(moved, 50 + 2 * 4);
        for a in c.scene.animations() {
            for ch in &a.channels {
                match &ch.curve {
                    Curve::Translation(s) => assert!(s.sample(0.0).abs_diff_eq(s.sample(a.duration()), 1e-4)),
                    Curve::Rotation(s) => assert!(s.sample(0.0).angle_between(s.sample(a.duration())) < 1e-3),
                    Curve::Scale(s) => assert!(s.sample(0.0).abs_diff_eq(s.sample(a.duration()), 1e-4)),
                }
            }
        }
    }

    #[test]
    fn same_seed_same_traffic() {
        let (mut a, mut b) = (city_with_traffic(&small(40)).unwrap(), city_with_traffic(&small(40)).unwrap());
        for s in [&mut a.scene, &mut b.scene] {
            s.animate(7.3).unwrap();
            s.update_transforms();
        }
        let (ia, ib) = (a.scene.instances(), b.scene.instances());
        assert_eq!(ia.len(), ib.len());
        assert!(ia.iter().zip(&ib).all(|(x, y)| x.world_from_local == y.world_from_local));
    }

    /// The crane's parts move relative to their parents, and the hook clears the buildings
    /// under it over a whole period.
    #[test]
    fn cranes_are_nested_and_clear_the_roofs() {
        let mut c = city_with_traffic(&small(0)).unwrap();
        let houses = buildings(&c.scene);
        let id = |name: &str| c.scene.find(name).unwrap();
        let (mast, jib, trolley, hook) =
            (id("crane 0 mast"), id("crane 0 jib"), id("crane 0 trolley"), id("crane 0 hook"));
        let parent = |n| c.scene.node(n).unwrap().parent();
        assert_eq!((parent(jib), parent(trolley), parent(hook)), (Some(mast), Some(jib), Some(trolley)));
        let local = |s: &Scene, n| s.node(n).unwrap().local_transform();
        let (j0, t0, h0) = (local(&c.scene, jib), local(&c.scene, trolley), local(&c.scene, hook));
        c.scene.animate(5.0).unwrap();
        let (j1, t1, h1) = (local(&c.scene, jib), local(&c.scene, trolley), local(&c.scene, hook));
        assert!(j0.rotation.angle_between(j1.rotation) > 0.1, "the jib turns");
        assert_eq!(j0.translation, j1.translation, "the jib stays on the mast top");
        assert!(
            t1.translation.x > t0.translation.x + 1.0 && t1.translation.yz() == t0.translation.yz(),
            "the trolley slides"
        );
        assert!(
            h1.translation.y < h0.translation.y - 0.5 && h1.translation.xz() == h0.translation.xz(),
            "the hook goes down"
        );
        for step in 0..=96 {
            c.scene.animate(step as f32 * 0.5).unwrap();
            c.scene.update_transforms();
            let hook = c.scene.node(hook).unwrap();
            let w = hook.world_aabb();
            // The hook's world position is the composition of its ancestors' transforms.
            let composed = c.scene.node(trolley).unwrap().world_matrix() * hook.local_matrix();
            assert!(composed.abs_diff_eq(hook.world_matrix(), 1e-4));
            for h in houses.iter().filter(|h| h.intersects(&Aabb::new(w.min.with_y(0.0), w.max))) {
                assert!(w.min.y > h.max.y, "hook {w:?} in a building {h:?}");
            }
        }
    }
}

//! Every call the viewer and the walkthrough make into sightline, in one place: build or
//! load a scene, decide where the camera starts (and which way a walkthrough goes), render a
//! frame with a chosen visibility method, and the extra pictures the viewer shows — the
//! edges of the triangles a frame shows, a level of the z-pyramid, and cluster boxes
//! classified as outside the view, hidden, or visible. The rest of both programs only moves
//! cameras and pixels around, so a change of the library's API touches this file alone.
//!
//! A `World` holds the scene with its culler and ray caster: a frame after the scene's
//! animations moved it ([`Engine::animate`]) brings both up to date before drawing.
//!
//! Framing. A scene without a street layout is seen from a three-quarter view (from the
//! front-right, 28° above the horizon) at the distance where its bounding sphere fits both
//! the vertical and the horizontal field of view: a sphere of radius r seen under a half
//! angle θ fills it at distance r / sin θ. The walkthrough circles the scene at that
//! distance. The built-in city starts on its street walk instead.

use std::time::Instant;

use anyhow::{bail, Result};
use glam::{DVec2, Vec3, Vec4};
use sightline::render::hzb::DepthPyramid;
use sightline::render::{self, BoxVisibility, DrawItem, RenderOptions, ShadeOptions, Visibility, World};
use sightline::scene::builders::CityLayout;
use sightline::scene::path::CameraKey;
use sightline::scene::Aabb;
pub use sightline::scene::Camera;
use sightline::SceneSpec;

/// The frame the engine draws into, and the colour maps of its ID and depth-test pictures.
pub use sightline::render::output::{heat_color, id_color};
pub use sightline::render::Framebuffer;

/// A visibility method the programs offer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// Every triangle through the pipeline
    Brute,
    /// View-frustum culling of clusters (BVH)
    Frustum,
    /// Frustum plus occlusion culling against a z-pyramid, last frame's visible set first
    Hzb,
    /// Greene's octree walk with z-pyramid tests
    OctreeHzb,
    /// One ray per pixel through a two-level BVH
    Raycast,
}

impl Method {
    /// The methods in the order of the viewer's keys 1–5.
    pub const ALL: [Method; 5] = [Method::Brute, Method::Frustum, Method::Hzb, Method::OctreeHzb, Method::Raycast];

    /// The name on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self.culling() {
            Some(m) => m.name(),
            None => "raycast",
        }
    }

    fn culling(self) -> Option<render::Method> {
        match self.visibility() {
            Visibility::Cull(m) => Some(m),
            Visibility::RayCast => None,
        }
    }

    fn visibility(self) -> Visibility {
        match self {
            Method::Brute => render::Method::Brute.into(),
            Method::Frustum => render::Method::Frustum.into(),
            Method::Hzb => render::Method::Hzb.into(),
            Method::OctreeHzb => render::Method::OctreeHzb.into(),
            Method::Raycast => Visibility::RayCast,
        }
    }
}

/// Where a camera is and how it sees (up is +y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub eye: Vec3,
    pub target: Vec3,
    pub fov_deg: f32,
    pub near: f32,
    pub far: f32,
}

impl Pose {
    pub fn from_key(k: &CameraKey) -> Pose {
        Pose { eye: k.eye.into(), target: k.target.into(), fov_deg: k.fovy_deg, near: k.near, far: k.far }
    }
}

/// Where the viewer starts: the fly camera's pose there, and the camera drawn exactly
/// until the first move.
#[derive(Debug, Clone, Copy)]
pub struct StartView {
    pub pose: Pose,
    pub exact: Exact,
}

/// The camera a start view draws before the first move.
#[derive(Debug, Clone, Copy)]
pub enum Exact {
    /// The scene file's camera N.
    File(usize),
    /// A path's frame or `--eye --target`, its up direction kept.
    Key(CameraKey),
    /// The pose itself (+y up).
    Pose,
}

/// What one frame did and cost.
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameInfo {
    /// Milliseconds in the renderer (culling, drawing, shading or tracing).
    pub ms: f64,
    /// Triangles sent to the rasterizer (`None` for ray casting).
    pub triangles_drawn: Option<u64>,
    /// Clusters drawn and clusters in the scene (`None` for ray casting).
    pub clusters: Option<(u64, u64)>,
    /// Clusters skipped: outside the frustum, facing away, hidden.
    pub culled: (u64, u64, u64),
    /// Milliseconds culling, drawing and shading (`None` for ray casting).
    pub stages: Option<[f64; 3]>,
}

/// Cluster boxes and what a camera's finished frame says of each: outside its view, hidden
/// behind what it drew, or (partly) visible.
#[derive(Debug, Clone)]
pub struct ClassifiedBoxes {
    pub boxes: Vec<Aabb>,
    pub classes: Vec<BoxVisibility>,
    /// The camera that classified them (its frustum is drawn when another camera looks on).
    pub camera: Camera,
}

impl ClassifiedBoxes {
    /// Boxes outside the view, hidden, visible.
    pub fn counts(&self) -> [usize; 3] {
        let n = |v| self.classes.iter().filter(|c| **c == v).count();
        [n(BoxVisibility::OutsideView), n(BoxVisibility::Occluded), n(BoxVisibility::Visible)]
    }
}

/// A z-pyramid level as an image of depths.
pub struct LevelImage {
    /// The level shown (0 is the depth buffer) and the number of levels.
    pub level: usize,
    pub levels: usize,
    pub width: u32,
    pub height: u32,
    pub texels: Vec<f32>,
}

/// A scene and the state that draws it frame after frame.
pub struct Engine {
    world: World,
    /// The street grid of a built-in city (its walk is where the camera starts).
    layout: Option<CityLayout>,
    opts: RenderOptions,
    /// Bounds at load time (animations move things within the scene's reach).
    bounds: Aabb,
    triangles: u64,
    /// Each instance's first triangle, to find a triangle ID's instance.
    starts: Vec<u32>,
    /// Cluster boxes and the scene revision they were taken at.
    cluster_boxes: Option<(u64, Vec<Aabb>)>,
}

/// Box edges as corner pairs (corner bit 0: x, 1: y, 2: z at the max side).
const BOX_EDGES: [(usize, usize); 12] =
    [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)];

impl Engine {
    /// Builds or loads the scene `spec`; `allowed_roots` are folders besides a scene file's
    /// own that it may read from.
    pub fn load(spec: &SceneSpec, allowed_roots: &[std::path::PathBuf]) -> Result<Engine> {
        let options = sightline::scene::LoadOptions { allowed_roots: allowed_roots.to_vec(), ..Default::default() };
        // The loader's errors name the file.
        let loaded = spec.load_with(&options)?;
        let bounds = loaded.scene.world_aabb();
        if bounds.is_empty() {
            bail!("the scene {} has no triangles to draw", describe(spec));
        }
        // NaN lengths fail the `<` too.
        let placeable = bounds.extent().length() < 1e30;
        if !bounds.is_finite() || !placeable {
            let (lo, hi) = (bounds.min, bounds.max);
            bail!("the scene {} is too large to place a camera in (bounds {lo} to {hi})", describe(spec));
        }
        for w in &loaded.scene.warnings {
            eprintln!("warning: {w}");
        }
        let mut world = World::new(loaded.scene);
        // The culler now, not in the first frame; the ray caster when first asked for.
        let culler = world.culler()?;
        let starts: Vec<u32> = culler.instances().iter().map(|i| i.first_triangle).collect();
        let triangles = culler.instances().iter().map(|i| i.triangle_count as u64).sum();
        Ok(Engine {
            world,
            layout: loaded.layout,
            // The pictures' look (sky, light) at one sample per pixel: `sightline render
            // --aa off` draws the same pixels.
            opts: RenderOptions { shading: ShadeOptions::picture(), ..RenderOptions::default() },
            bounds,
            triangles,
            starts,
            cluster_boxes: None,
        })
    }

    /// True when the scene has animations to play.
    pub fn animated(&self) -> bool {
        !self.world.scene().animations().is_empty()
    }

    /// Poses the scene's animations at `t` seconds; the next frame shows the pose.
    pub fn animate(&mut self, t: f32) -> Result<()> {
        self.world.animate(t)?;
        Ok(())
    }

    /// Triangles in the scene.
    pub fn triangles(&self) -> u64 {
        self.triangles
    }

    /// Eye height above the ground for walking: a person's in a city, else 5% of the
    /// scene's height.
    pub fn eye_height(&self) -> f32 {
        if self.layout.is_some() {
            sightline::scene::path::EYE_HEIGHT
        } else {
            (self.bounds.extent().y * 0.05).max(1e-3)
        }
    }

    /// Height of the ground (the bottom of the scene).
    pub fn ground(&self) -> f32 {
        self.bounds.min.y
    }

    /// A comfortable flying speed in scene units per second: a brisk run in a city, else
    /// the scene's diagonal in about seven seconds.
    pub fn base_speed(&self) -> f32 {
        if self.layout.is_some() {
            12.0
        } else {
            (self.bounds.extent().length() * 0.15).max(1e-3)
        }
    }

    /// Where the camera starts: the first frame of the street walk in a city, else the
    /// three-quarter view that fits the scene.
    pub fn start_pose(&self, aspect: f32) -> Result<Pose> {
        if self.layout.is_some() {
            return Ok(self.walk_path(1, aspect)?[0]);
        }
        Ok(orbit_pose(&self.bounds, aspect, 0.0))
    }

    /// A walkthrough of `frames` frames: the street walk in a city, else one orbit around
    /// the scene at the framing distance.
    pub fn walk_path(&self, frames: usize, aspect: f32) -> Result<Vec<Pose>> {
        if let Some(l) = &self.layout {
            return Ok(sightline::street_walk(l, frames).iter().map(Pose::from_key).collect());
        }
        let n = frames.max(1);
        Ok((0..n).map(|i| orbit_pose(&self.bounds, aspect, std::f32::consts::TAU * i as f32 / n as f32)).collect())
    }

    /// The camera `sightline render --eye --target [--up] --fov [--near] [--far]` makes: near
    /// 0.1 and the far plane half again past the far side of the scene unless given.
    pub fn key_like_render(
        &self,
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        fov: f32,
        near: Option<f32>,
        far: Option<f32>,
    ) -> CameraKey {
        let far = far.unwrap_or_else(|| self.far_for(eye));
        CameraKey {
            eye: eye.into(),
            target: target.into(),
            up: up.into(),
            fovy_deg: fov,
            near: near.unwrap_or(0.1),
            far,
        }
    }

    /// The camera of the start view for an image of this aspect: exactly what the options
    /// named (a file's camera, a path's frame with its up, an eye and target with --up).
    pub fn start_camera(&self, start: &StartView, aspect: f32) -> Result<Camera> {
        match &start.exact {
            Exact::File(n) => Ok(self.file_camera(*n, aspect)?.0),
            Exact::Key(key) => Ok(key.camera(aspect)?),
            Exact::Pose => self.camera(&start.pose, aspect),
        }
    }

    /// A far plane half again past the far side of the scene as seen from `eye` (what
    /// `render` chooses).
    pub fn far_for(&self, eye: Vec3) -> f32 {
        let b = self.bounds;
        ((b.center() - eye).length() + b.extent().length()).max(1.0) * 1.5
    }

    /// The scene file's camera `n` for an image of this aspect (what `sightline render
    /// --camera N` draws through), and the fly camera's pose that starts where it is.
    pub fn file_camera(&self, n: usize, aspect: f32) -> Result<(Camera, Pose)> {
        let scene = self.world.scene();
        let camera = match scene.camera(n, aspect) {
            Err(sightline::scene::Error::NoSuchCamera { count, .. }) => {
                let has = match count {
                    0 => "no cameras".to_string(),
                    1 => "1 camera (--camera 0)".to_string(),
                    c => format!("{c} cameras (--camera 0 to {})", c - 1),
                };
                bail!("--camera {n}, but the scene has {has}")
            }
            c => c.map_err(|e| anyhow::anyhow!("--camera {n}: {e}"))?,
        };
        let (_, _, bottom, top, near, far, perspective) = camera.projection.bounds();
        // A parallel camera has no field of view: the fly camera takes 60°.
        let fov_deg = if perspective {
            ((top as f64 / near as f64).atan() - (bottom as f64 / near as f64).atan()).to_degrees() as f32
        } else {
            60.0
        };
        let eye = camera.view.eye;
        let pose = Pose { eye, target: eye + camera.view.forward(), fov_deg, near, far };
        Ok((camera, pose))
    }

    /// A `width × height` picture seen by `camera`, supersampled `s × s` (the walkthrough's
    /// PNG frames): ray cast when `method` is, else rasterized with frustum culling (the
    /// same pixels as any culling method, and no state that a timed frame's culling keeps).
    #[allow(dead_code)] // the walkthrough's
    pub fn picture(&mut self, camera: &Camera, method: Method, width: u32, height: u32, s: u32) -> Result<Framebuffer> {
        let visibility = match method {
            Method::Raycast => Visibility::RayCast,
            _ => render::Method::Frustum.into(),
        };
        let (world, opts) = (&mut self.world, &self.opts);
        render::aa::supersample(width, height, s, |fb| -> Result<()> {
            world.render(camera, visibility, fb, opts)?;
            Ok(())
        })
    }

    /// The camera of a pose for an image of this aspect (width / height).
    pub fn camera(&self, p: &Pose, aspect: f32) -> Result<Camera> {
        let key = CameraKey {
            eye: p.eye.into(),
            target: p.target.into(),
            up: [0.0, 1.0, 0.0],
            fovy_deg: p.fov_deg,
            near: p.near,
            far: p.far,
        };
        Ok(key.camera(aspect)?)
    }

    /// Renders one frame with `method` into `fb` (every plane; depth tests are counted when
    /// `fb` counts them and the method rasterizes).
    pub fn render(&mut self, camera: &Camera, method: Method, fb: &mut Framebuffer) -> Result<FrameInfo> {
        let t = Instant::now();
        let report = self.world.render(camera, method.visibility(), fb, &self.opts)?;
        let info = match report.cull {
            Some(cs) => FrameInfo {
                ms: 0.0,
                triangles_drawn: Some(cs.triangles_drawn),
                clusters: Some((cs.clusters_drawn, cs.clusters)),
                culled: (cs.culled_by_frustum, cs.culled_by_backface, cs.culled_by_occlusion),
                stages: Some([cs.ms_cull, cs.ms_draw, cs.ms_shading]),
            },
            None => {
                if let Some(c) = &mut fb.depth_tests {
                    c.fill(0); // rays make no depth tests: an empty heat map, not a stale one
                }
                FrameInfo::default()
            }
        };
        Ok(FrameInfo { ms: t.elapsed().as_secs_f64() * 1e3, ..info })
    }

    /// Draws the edges of the triangles `fb` shows (those with an ID in it) over its
    /// colour; returns how many triangles that was.
    pub fn draw_visible_edges(&mut self, camera: &Camera, fb: &mut Framebuffer) -> Result<usize> {
        let n = self.triangles as usize;
        let mut seen = vec![0u64; n.div_ceil(64)];
        for &id in &fb.ids {
            if id != 0 && (id as usize) <= n {
                let t = id as usize - 1;
                seen[t / 64] |= 1 << (t % 64);
            }
        }
        let mut items: Vec<DrawItem> = Vec::new();
        for (w, &bits) in seen.iter().enumerate() {
            let mut b = bits;
            while b != 0 {
                let t = (w * 64 + b.trailing_zeros() as usize) as u32;
                b &= b - 1;
                let inst = self.starts.partition_point(|&s| s <= t).saturating_sub(1);
                let first = t - self.starts[inst];
                match items.last_mut() {
                    Some(d) if d.instance == inst as u32 && d.first + d.count == first => d.count += 1,
                    _ => items.push(DrawItem { instance: inst as u32, first, count: 1 }),
                }
            }
        }
        let drawn = items.iter().map(|d| d.count as usize).sum();
        let (culler, scene) = self.world.culler_and_scene()?;
        render::wire::draw_wireframe(scene, culler.instances(), &items, camera, fb, &self.opts)?;
        Ok(drawn)
    }

    /// Level `level` (clamped to the pyramid) of the max-depth pyramid over `fb`'s depth.
    pub fn pyramid_level(fb: &Framebuffer, level: usize) -> LevelImage {
        let mut p = DepthPyramid::new(fb.width(), fb.height());
        let levels = p.level_count();
        let level = level.min(levels - 1);
        match level {
            0 => LevelImage { level, levels, width: fb.width(), height: fb.height(), texels: fb.depth.to_vec() },
            k => {
                p.build(&fb.depth);
                let l = p.level(k).expect("level within the count");
                LevelImage { level, levels, width: l.width, height: l.height, texels: l.texels.clone() }
            }
        }
    }

    /// Every cluster box, classified against the frame `camera` sees at `width × height`:
    /// outside its view, hidden behind the frame's finished depth, or visible.
    pub fn classify_clusters(&mut self, camera: &Camera, width: u32, height: u32) -> Result<ClassifiedBoxes> {
        let (culler, scene) = self.world.culler_and_scene()?;
        let revision = scene.revision();
        let boxes = match self.cluster_boxes.take() {
            // Taken again once the scene has moved.
            Some((r, b)) if r == revision => b,
            _ => culler.clustered().item_boxes(culler.instances()),
        };
        let mut probe = Framebuffer::new(width, height)?;
        let mut classes = Vec::new();
        {
            let (_, _, pass) = culler.occluder_pass_with(camera, &mut probe, &self.opts, true)?;
            pass.test_batch(&boxes, &mut classes);
        }
        self.cluster_boxes = Some((revision, boxes.clone()));
        Ok(ClassifiedBoxes { boxes, classes, camera: *camera })
    }

    /// Draws the boxes' edges into `fb`'s colour as `camera` sees them: outside the view
    /// blue, hidden red, visible green (in that order, so visible ones end on top); when
    /// `camera` is not the one that classified them, also that camera's frustum in yellow.
    pub fn draw_boxes(&self, camera: &Camera, fb: &mut Framebuffer, c: &ClassifiedBoxes) {
        const COLORS: [(BoxVisibility, [u8; 4]); 3] = [
            (BoxVisibility::OutsideView, [70, 120, 255, 255]),
            (BoxVisibility::Occluded, [235, 60, 50, 255]),
            (BoxVisibility::Visible, [40, 230, 90, 255]),
        ];
        let m = camera.clip_from_world();
        for (class, rgba) in COLORS {
            for (b, _) in c.boxes.iter().zip(&c.classes).filter(|(_, k)| **k == class) {
                let corner = |i: usize| {
                    let p = Vec3::new(
                        if i & 1 == 0 { b.min.x } else { b.max.x },
                        if i & 2 == 0 { b.min.y } else { b.max.y },
                        if i & 4 == 0 { b.min.z } else { b.max.z },
                    );
                    m * p.extend(1.0)
                };
                let corners: [Vec4; 8] = std::array::from_fn(corner);
                for (i, j) in BOX_EDGES {
                    line(fb, corners[i], corners[j], rgba);
                }
            }
        }
        if c.camera.clip_from_world() != m {
            // The classifying camera's frustum: the NDC cube's corners taken back to the world.
            let world_from_clip = c.camera.clip_from_world().inverse();
            let corners: [Vec4; 8] = std::array::from_fn(|i| {
                let ndc = Vec4::new(
                    if i & 1 == 0 { -1.0 } else { 1.0 },
                    if i & 2 == 0 { -1.0 } else { 1.0 },
                    if i & 4 == 0 { -1.0 } else { 1.0 },
                    1.0,
                );
                let w = world_from_clip * ndc;
                m * (w / w.w)
            });
            for (i, j) in BOX_EDGES {
                line(fb, corners[i], corners[j], [255, 230, 40, 255]);
            }
        }
    }
}

/// A clip-space segment clipped to the near plane (z ≥ −w), projected and drawn.
fn line(fb: &mut Framebuffer, mut a: Vec4, mut b: Vec4, rgba: [u8; 4]) {
    let (da, db) = (a.z + a.w, b.z + b.w);
    if da < 0.0 && db < 0.0 {
        return;
    }
    if da < 0.0 {
        a = a + (b - a) * (da / (da - db));
    } else if db < 0.0 {
        b = b + (a - b) * (db / (db - da));
    }
    let (w, h) = (fb.width(), fb.height());
    let win = |p: Vec4| {
        let w_ = (p.w as f64).max(1e-9);
        DVec2::new((p.x as f64 / w_ + 1.0) * 0.5 * w as f64, (1.0 - p.y as f64 / w_) * 0.5 * h as f64)
    };
    render::wire::draw_line(&mut fb.color, w, h, win(a), win(b), rgba);
}

/// The camera on the circle around the scene's bounds at the distance where its bounding
/// sphere fits the view, `turn` radians around the vertical from the front-right
/// three-quarter view, 28° above the horizon, looking at the center.
fn orbit_pose(b: &Aabb, aspect: f32, turn: f32) -> Pose {
    let fov_deg = 60.0f32;
    let c = b.center();
    let r = (b.extent().length() * 0.5).max(1e-3);
    let half_y = fov_deg.to_radians() * 0.5;
    let half_x = (half_y.tan() * aspect.max(1e-3)).atan();
    let dist = r / half_y.min(half_x).sin() * 1.05;
    let azimuth = std::f32::consts::FRAC_PI_4 + turn;
    let elevation = 28f32.to_radians();
    let dir = Vec3::new(azimuth.sin() * elevation.cos(), elevation.sin(), azimuth.cos() * elevation.cos());
    let near = ((dist - r) * 0.9).max(dist * 1e-3);
    Pose { eye: c + dir * dist, target: c, fov_deg, near, far: (dist + r) * 1.5 }
}

/// The scene as a user named it.
pub fn describe(spec: &SceneSpec) -> String {
    match spec {
        SceneSpec::City(n) if *n == sightline::DEFAULT_CITY_TRIANGLES => "city".into(),
        SceneSpec::City(n) => format!("city:{n}"),
        SceneSpec::CityTraffic(n) => format!("city+traffic:{n}"),
        SceneSpec::Boxfield => "boxfield".into(),
        SceneSpec::File(p) => p.display().to_string(),
    }
}

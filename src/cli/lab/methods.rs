//! The lab's method table: every visibility method the lab runs, one entry each.
//!
//! An entry names the method, the most triangles it takes, when it applies, and a function
//! that draws the view into a framebuffer (IDs and depth; the lab shades afterwards) and
//! returns its time and counters. Adding a method of `sightline_render::visibility` is one
//! line: `LabMethod::soup("name", module::MAX_TRIANGLES, |s, c, fb| module::render(s, c, fb))`.

use std::time::Instant;

use anyhow::Result;
use sightline::render::transparency::{render_abuffer, render_depth_peeling, scene_has_transparency};
use sightline::render::visibility::bsp::{self, BspMode};
use sightline::render::visibility::{painter, warnock, Counters, Soup};
use sightline::render::{
    CullStats, Culler, FrameStats, Framebuffer, Method, RayCaster, RaycastOptions, RenderOptions, TransparencyStats,
};
use sightline::scene::{Camera, Scene};

/// What one run of a method gave.
#[derive(Debug, Clone)]
pub struct Ran {
    /// Wall time of the visibility work, milliseconds (building the method's structures,
    /// which a program does once, and shading are not counted).
    pub ms: f64,
    /// What the method did.
    pub counters: Counters,
    /// The method drew its own colours (blending), which shading from IDs would lose.
    pub shaded: bool,
}

/// The view the methods draw, and what they share: the scene, its triangle soup, and the
/// culler and ray caster, built on first use.
pub struct Lab<'a> {
    pub scene: &'a Scene,
    pub soup: Soup,
    culler: Option<Culler>,
    caster: Option<RayCaster>,
    /// The A-buffer's frame (colours and its deepest pixel's layer count), once drawn: what
    /// depth peeling is measured against.
    abuffer: Option<(Vec<[u8; 4]>, u32)>,
}

impl<'a> Lab<'a> {
    /// The lab of `scene` (transforms propagated).
    pub fn new(scene: &'a Scene) -> Result<Lab<'a>> {
        Ok(Lab { scene, soup: Soup::from_scene(scene)?, culler: None, caster: None, abuffer: None })
    }
}

/// A soup method: `sightline_render::visibility`'s contract.
pub type SoupFn = fn(&Soup, &Camera, &mut Framebuffer) -> sightline::render::Result<Counters>;

/// How a method draws: from the scene through the engine's structures, or from the soup.
#[derive(Clone, Copy)]
pub enum Runner {
    /// Draws from the lab's scene (z-buffer, HZB, ray casting).
    Scene(fn(&mut Lab, &Camera, &mut Framebuffer) -> Result<Ran>),
    /// Draws the lab's soup.
    Soup(SoupFn),
}

/// One row of the table.
#[derive(Clone, Copy)]
pub struct LabMethod {
    /// The name (see the command-line reference: scripts read it).
    pub name: &'static str,
    /// The most triangles the method takes; larger scenes are refused, not run.
    pub limit: Option<usize>,
    /// Whether the method has something to show for the scene (transparency methods need
    /// transparent materials); methods that do not apply are left out.
    pub applies: fn(&Scene) -> bool,
    /// How it draws.
    pub run: Runner,
}

impl LabMethod {
    /// A method of `sightline_render::visibility` taking at most `limit` triangles.
    pub const fn soup(name: &'static str, limit: usize, run: SoupFn) -> LabMethod {
        LabMethod { name, limit: Some(limit), applies: always, run: Runner::Soup(run) }
    }

    /// Draws the view into `fb` (IDs and depth) and times it.
    pub fn draw(&self, lab: &mut Lab, camera: &Camera, fb: &mut Framebuffer) -> Result<Ran> {
        match self.run {
            Runner::Scene(f) => f(lab, camera, fb),
            Runner::Soup(f) => {
                let t = Instant::now();
                let counters = f(&lab.soup, camera, fb)?;
                Ok(Ran { ms: ms_since(t), counters, shaded: false })
            }
        }
    }
}

/// Every scene.
pub fn always(_: &Scene) -> bool {
    true
}

/// The methods, the referee first.
pub const METHODS: &[LabMethod] = &[
    LabMethod { name: "zbuffer", limit: None, applies: always, run: Runner::Scene(zbuffer) },
    LabMethod { name: "hzb", limit: None, applies: always, run: Runner::Scene(hzb) },
    LabMethod { name: "raycast", limit: None, applies: always, run: Runner::Scene(raycast) },
    LabMethod::soup("bsp", bsp::LIMIT, |s, c, fb| bsp::render(s, c, fb, BspMode::BackToFront)),
    LabMethod::soup("painter", painter::LIMIT, painter::render),
    LabMethod::soup(warnock::NAME, warnock::MAX_TRIANGLES, warnock::render),
    // O(n log n) and no tests: shown for how many pixels it gets wrong.
    LabMethod { name: "centroid-sort", limit: None, applies: always, run: Runner::Soup(painter::render_centroid_sort) },
    // Transparency, on scenes with blended materials: the A-buffer (the reference), depth
    // peeling with as many layers as the A-buffer's deepest pixel has, and with one and two
    // layers, to show how the picture degrades.
    LabMethod { name: "abuffer", limit: None, applies: scene_has_transparency, run: Runner::Scene(abuffer) },
    LabMethod { name: "depth-peeling", limit: None, applies: scene_has_transparency, run: Runner::Scene(peel_all) },
    LabMethod { name: "depth-peeling-1", limit: None, applies: scene_has_transparency, run: Runner::Scene(peel_1) },
    LabMethod { name: "depth-peeling-2", limit: None, applies: scene_has_transparency, run: Runner::Scene(peel_2) },
];

/// The referee's name: every other method is compared with it.
pub const REFEREE: &str = "zbuffer";

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Visibility only: the lab shades every method's IDs the same way afterwards.
fn ids_only() -> RenderOptions {
    RenderOptions::ids_only()
}

/// A culling method of the engine's culler (built on first use, not timed).
fn cull(lab: &mut Lab, camera: &Camera, fb: &mut Framebuffer, method: Method) -> Result<Ran> {
    let scene = lab.scene;
    let culler = lab.culler.get_or_insert_with(|| Culler::new(scene));
    let t = Instant::now();
    let (cs, fs) = culler.render(scene, camera, method, fb, &ids_only())?;
    let ms = ms_since(t);
    Ok(Ran { ms, counters: cull_counters(&cs, &fs), shaded: false })
}

fn cull_counters(cs: &CullStats, fs: &FrameStats) -> Counters {
    let mut c = Counters::new();
    for (name, v) in [
        ("clusters", cs.clusters),
        ("culled_by_frustum", cs.culled_by_frustum),
        ("culled_by_backface", cs.culled_by_backface),
        ("culled_by_occlusion", cs.culled_by_occlusion),
        ("occlusion_tests", cs.occlusion_tests),
        ("occluded_boxes", cs.occluded_boxes),
        ("clusters_drawn", cs.clusters_drawn),
        ("triangles_drawn", cs.triangles_drawn),
        ("fragments_tested", fs.fragments_tested),
        ("fragments_written", fs.fragments_written),
    ] {
        c.add(name, v);
    }
    c
}

/// The brute-force rasterizer: every triangle, z-buffer (the referee).
fn zbuffer(lab: &mut Lab, camera: &Camera, fb: &mut Framebuffer) -> Result<Ran> {
    cull(lab, camera, fb, Method::Brute)
}

/// Frustum and occlusion culling with the hierarchical z-buffer.
fn hzb(lab: &mut Lab, camera: &Camera, fb: &mut Framebuffer) -> Result<Ran> {
    cull(lab, camera, fb, Method::Hzb)
}

/// One primary ray per pixel through the two-level BVH (built on first use, not timed).
fn raycast(lab: &mut Lab, camera: &Camera, fb: &mut Framebuffer) -> Result<Ran> {
    if lab.caster.is_none() {
        lab.caster = Some(RayCaster::build(lab.scene)?);
    }
    let caster = lab.caster.as_ref().expect("built above");
    let t = Instant::now();
    let st = caster.render(lab.scene, camera, fb, &RaycastOptions::from_render(&ids_only()))?;
    let ms = ms_since(t);
    let mut c = Counters::new();
    c.add("primary_rays", st.primary_rays);
    c.add("hits", st.hits);
    Ok(Ran { ms, counters: c, shaded: false })
}

fn transparency_counters(st: &TransparencyStats) -> Counters {
    let mut c = Counters::new();
    c.add("blended_triangles", st.blended_triangles);
    c.add("masked_triangles", st.masked_triangles);
    c.add("fragments", st.fragments);
    c.add("fragments_drawn", st.fragments_drawn);
    c.add("pixels_with_fragments", st.pixels);
    c.add("max_fragments_per_pixel", st.max_fragments_per_pixel as u64);
    c
}

/// How every method's frame is shaded for the contact sheet: the pictures' light and sky.
pub fn look() -> RenderOptions {
    RenderOptions { shading: sightline::render::ShadeOptions::picture(), ..RenderOptions::default() }
}

/// Blended materials by per-pixel fragment lists, sorted and composited (the reference);
/// shaded by the method itself.
fn abuffer(lab: &mut Lab, camera: &Camera, fb: &mut Framebuffer) -> Result<Ran> {
    let t = Instant::now();
    let st = render_abuffer(lab.scene, camera, fb, &look())?;
    let ms = ms_since(t);
    lab.abuffer = Some((fb.color.to_vec(), st.max_fragments_per_pixel));
    Ok(Ran { ms, counters: transparency_counters(&st), shaded: true })
}

/// Depth peeling with `layers` layers (all the A-buffer needed when `None`); its counters
/// add how many pixels' colours differ from the A-buffer's by more than 1/255.
fn peel(lab: &mut Lab, camera: &Camera, fb: &mut Framebuffer, layers: Option<u32>) -> Result<Ran> {
    if lab.abuffer.is_none() {
        let mut scratch = Framebuffer::new(fb.width(), fb.height())?;
        abuffer(lab, camera, &mut scratch)?;
    }
    let (reference, deepest) = lab.abuffer.as_ref().expect("drawn above");
    let layers = layers.unwrap_or(*deepest).max(1);
    let t = Instant::now();
    let st = render_depth_peeling(lab.scene, camera, fb, layers, &look())?;
    let ms = ms_since(t);
    let off = |a: &[u8; 4], b: &[u8; 4]| a.iter().zip(b).any(|(x, y)| x.abs_diff(*y) > 1);
    let differ = reference.iter().zip(&fb.color).filter(|(a, b)| off(a, b)).count();
    let mut c = transparency_counters(&st);
    c.add("layers", layers as u64);
    c.add("pixels_differing_from_abuffer", differ as u64);
    Ok(Ran { ms, counters: c, shaded: true })
}

fn peel_all(lab: &mut Lab, camera: &Camera, fb: &mut Framebuffer) -> Result<Ran> {
    peel(lab, camera, fb, None)
}

fn peel_1(lab: &mut Lab, camera: &Camera, fb: &mut Framebuffer) -> Result<Ran> {
    peel(lab, camera, fb, Some(1))
}

fn peel_2(lab: &mut Lab, camera: &Camera, fb: &mut Framebuffer) -> Result<Ran> {
    peel(lab, camera, fb, Some(2))
}

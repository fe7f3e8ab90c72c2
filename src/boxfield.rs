//! The occlusion benchmark of record: the boxfield seen from eye height, its occluders drawn
//! depth-only into the z-buffer and pyramid, then 100,000 box queries.
//!
//! Shared by `benches/culling.rs`, `examples/boxfield.rs` and the tests, so all three
//! measure and check the same thing.

use glam::{Affine3A, Vec3};
use sightline_render::{BoxVisibility, Culler, DrawSource, Framebuffer, RenderOptions, Renderer};
use sightline_scene::builders::{boxfield, boxfield_queries, BoxfieldParams};
use sightline_scene::path::CameraKey;
use sightline_scene::{shapes, Aabb, Camera, Scene};

/// Image size of the benchmark.
pub const SIZE: (u32, u32) = (1280, 720);
/// Number of query boxes.
pub const QUERIES: usize = 100_000;

/// The scene, camera and query boxes.
pub struct Boxfield {
    /// 83,334 boxes, 1,000,008 triangles.
    pub scene: Scene,
    /// Eye (0, 1.7, 0) looking along +z, fovy 60°, near 0.1.
    pub camera: Camera,
    /// Query boxes in the view wedge 2–100 units ahead.
    pub queries: Vec<Aabb>,
}

impl Boxfield {
    /// Builds the benchmark's scene, camera and `queries` query boxes.
    pub fn new(queries: usize) -> Self {
        let scene = boxfield(&BoxfieldParams::default()).expect("the default boxfield is valid");
        let aspect = SIZE.0 as f32 / SIZE.1 as f32;
        let camera = camera(aspect, 400.0);
        let queries = boxfield_queries(queries, 60f32.to_radians(), aspect, 7);
        Self { scene, camera, queries }
    }
}

/// The benchmark's camera for an `aspect` ratio and far plane: eye (0, 1.7, 0) looking along
/// +z, fovy 60°, near 0.1.
pub fn camera(aspect: f32, far: f32) -> Camera {
    let key = CameraKey {
        eye: [0.0, 1.7, 0.0],
        target: [0.0, 1.7, 1.0],
        up: [0.0, 1.0, 0.0],
        fovy_deg: 60.0,
        near: 0.1,
        far,
    };
    key.camera(aspect).expect("the benchmark camera is valid for any positive aspect and far > 0.1")
}

/// Counts of one run of the queries.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QueryCounts {
    /// Possibly visible.
    pub visible: usize,
    /// Occluded by the drawn boxes.
    pub occluded: usize,
    /// Outside the view frustum.
    pub outside: usize,
}

/// Draws the occluders and answers every query; returns the answers.
pub fn run_queries(culler: &mut Culler, bf: &Boxfield, fb: &mut Framebuffer) -> Vec<BoxVisibility> {
    let opts = RenderOptions::ids_only();
    let (_, _, q) = culler.occluder_pass(&bf.camera, fb, &opts).expect("drawing the occluders");
    let mut answers = Vec::new();
    q.test_many(&bf.queries, &mut answers);
    q.finish();
    answers
}

/// Tallies answers.
pub fn count(answers: &[BoxVisibility]) -> QueryCounts {
    let mut c = QueryCounts::default();
    for a in answers {
        match a {
            BoxVisibility::Visible => c.visible += 1,
            BoxVisibility::Occluded => c.occluded += 1,
            BoxVisibility::OutsideView => c.outside += 1,
        }
    }
    c
}

/// The brute-force check: draws every box reported occluded onto the finished occluder frame
/// `fb` (depth and IDs of the occluders). If any of them had a pixel passing the depth test,
/// some query box would win that pixel; so the check passes exactly when the ID buffer does
/// not change. Returns the number of pixels a "occluded" box won (0 when conservative).
pub fn check_occluded(bf: &Boxfield, answers: &[BoxVisibility], fb: &Framebuffer) -> usize {
    let cube = shapes::cube("query").expect("cube");
    let first = bf.scene.stats().triangles as u32 + 1;
    let sources: Vec<DrawSource> = bf
        .queries
        .iter()
        .zip(answers)
        .filter(|(_, a)| **a == BoxVisibility::Occluded)
        .map(|(b, _)| DrawSource {
            positions: cube.positions(),
            indices: cube.indices(),
            triangle_ids: None,
            world_from_local: Affine3A::from_scale_rotation_translation(
                b.extent().max(Vec3::splat(1e-6)),
                glam::Quat::IDENTITY,
                b.center(),
            ),
            first_triangle: first,
            first: 0,
            count: 12,
        })
        .collect();
    let mut after = fb.clone();
    // Both faces: a box seen from inside would show its back faces, conservatively.
    let opts = RenderOptions { backface_culling: false, ..RenderOptions::ids_only() };
    Renderer::new().draw_sources(&sources, &bf.camera, &mut after, &opts).expect("drawing the query boxes");
    after.ids.iter().zip(&fb.ids).filter(|(a, b)| a != b).count()
}

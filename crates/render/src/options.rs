//! What to draw and how: draw items and render options.

use serde::Serialize;
use sightline_scene::Instance;

use crate::depth::DepthFormat;
use crate::shading::ShadeOptions;
use crate::transparency::stats::Transparency;

/// One entry of a draw list: a triangle range of one instance. The renderer draws items in
/// the order given (triangles within an item in mesh order), which is what an occlusion
/// culler needs to submit clusters front to back.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct DrawItem {
    /// Index into the `instances` slice passed with the list.
    pub instance: u32,
    /// First triangle of the range, within the instance's mesh.
    pub first: u32,
    /// Number of triangles.
    pub count: u32,
}

impl DrawItem {
    /// The whole of instance number `index`.
    pub fn whole(index: u32, inst: &Instance) -> Self {
        Self { instance: index, first: 0, count: inst.triangle_count }
    }
}

/// A triangle range of indexed geometry that is not (or not directly) a scene mesh, e.g.
/// the meshlets of the occlusion culler; see [`crate::Renderer::draw_sources`].
#[derive(Debug, Clone, Copy)]
pub struct DrawSource<'a> {
    /// Vertex positions (local space).
    pub positions: &'a [glam::Vec3],
    /// Triangle indices into `positions`.
    pub indices: &'a [u32],
    /// For each triangle of `indices`, the triangle number its ID is made from (`None`: its
    /// own position in `indices`).
    pub triangle_ids: Option<&'a [u32]>,
    /// `world_from_local` of the instance.
    pub world_from_local: glam::Affine3A,
    /// Global index of the instance's triangle 0 (the ID written is `1 + first_triangle + id`).
    pub first_triangle: u32,
    /// First triangle of the range (in `indices`).
    pub first: u32,
    /// Number of triangles.
    pub count: u32,
}

/// Every instance, whole, in order.
pub fn draw_all(instances: &[Instance]) -> Vec<DrawItem> {
    instances.iter().enumerate().map(|(i, inst)| DrawItem::whole(i as u32, inst)).collect()
}

/// Supersampling antialiasing (ordered grid, box-filter resolve).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum Antialias {
    /// One sample per pixel, at its center.
    #[default]
    Off,
    /// 2 × 2 samples per pixel.
    Ssaa2x2,
    /// 4 × 4 samples per pixel.
    Ssaa4x4,
}

impl Antialias {
    /// Samples per pixel side.
    pub fn factor(self) -> u32 {
        match self {
            Antialias::Off => 1,
            Antialias::Ssaa2x2 => 2,
            Antialias::Ssaa4x4 => 4,
        }
    }
}

/// Wireframe drawing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum Wireframe {
    /// Filled triangles only.
    #[default]
    Off,
    /// Triangle edges drawn over the shaded image.
    Overlay,
    /// Only the edges, on the background (depth and IDs stay cleared).
    Only,
    /// Hidden-line removal: the edges drawn over the shaded image where they are not
    /// hidden, each line pixel depth-tested against the filled depth buffer (see
    /// [`crate::wire`] for the tolerance), so back and hidden edges disappear.
    HiddenLine,
}

/// How a frame is rendered.
///
/// ```
/// use glam::Vec3;
/// use sightline_render::{draw_all, Framebuffer, RenderOptions, Renderer, ShadingMode};
/// use sightline_scene::{shapes, Angle, Camera, LookAt, NodeDesc, Scene};
///
/// let mut scene = Scene::new();
/// let cube = scene.add_mesh(shapes::cube("cube")?);
/// scene.add_node(None, NodeDesc::new("cube").mesh(cube))?;
/// scene.update_transforms();
/// let look = LookAt { eye: Vec3::new(2.0, 1.5, 3.0), fovy: Angle::degrees(45.0), far: 100.0, ..LookAt::default() };
/// let camera = Camera::perspective(&look, 4.0 / 3.0)?;
///
/// let instances = scene.instances();
/// let items = draw_all(&instances); // or clusters, in any order, in batches via `draw`
/// let mut renderer = Renderer::new(); // keep it: its buffers are reused frame to frame
/// let mut fb = Framebuffer::new(64, 48)?;
/// let mut opts = RenderOptions::default();
/// let stats = renderer.render(&scene, &instances, &items, &camera, &mut fb, &opts)?;
/// assert_eq!(stats.triangles_in, 12);
/// assert!(stats.backface_culled >= 6);
/// assert!(fb.ids.iter().any(|&id| id != 0));
///
/// // IDs and depth only (what visibility needs): no shading pass.
/// opts.shading.mode = ShadingMode::None;
/// renderer.render(&scene, &instances, &items, &camera, &mut fb, &opts)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RenderOptions {
    /// Drop back faces (counter-clockwise in NDC is front). On by default.
    pub backface_culling: bool,
    /// Depth buffer precision.
    pub depth_format: DepthFormat,
    /// Shading (mode `None`: depth and IDs only).
    pub shading: ShadeOptions,
    /// Supersampling.
    pub antialias: Antialias,
    /// Wireframe mode.
    pub wireframe: Wireframe,
    /// Wireframe line color.
    pub wire_color: [u8; 4],
    /// Clear color.
    pub background: [u8; 4],
    /// Clip x and y against a wide guard band instead of the frustum (same pixels, fewer
    /// clipped triangles). On by default.
    pub guard_band: bool,
    /// How masked and blended materials are drawn (by default: alpha-tested, and by the
    /// A-buffer); see [`crate::transparency`].
    pub transparency: Transparency,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            backface_culling: true,
            depth_format: DepthFormat::F32,
            shading: ShadeOptions::default(),
            antialias: Antialias::Off,
            wireframe: Wireframe::Off,
            wire_color: [20, 20, 20, 255],
            // The references' sky (0.62, 0.76, 0.92).
            background: [158, 194, 235, 255],
            guard_band: true,
            transparency: Transparency::ABuffer,
        }
    }
}

impl RenderOptions {
    /// Depth and IDs only, no shading: the fastest path (what visibility needs).
    pub fn ids_only() -> Self {
        let mut o = Self::default();
        o.shading.mode = crate::shading::ShadingMode::None;
        o
    }
}

/// `world_from_local` equality used to reuse a clip matrix between consecutive sources.
#[inline]
pub(crate) fn same_matrix(a: &glam::Affine3A, b: &glam::Affine3A) -> bool {
    a.matrix3 == b.matrix3 && a.translation == b.translation
}

//! Shading shared by the rasterizer and the ray caster: flat, Gouraud and per-pixel Lambert
//! with one directional light plus ambient, base color from the material and its texture,
//! and optional depth cueing.
//!
//! * Lambert's cosine law: `I = ambient + diffuse · max(0, n·l)`; the color is
//!   `base · I + emissive` (glTF's emissive factor: light the surface gives off itself).
//! * Gouraud (1971): light the three vertices, interpolate the intensities.
//! * Per pixel ("Phong" normal interpolation, 1975): interpolate the normal, then light.
//! * Depth cueing (Foley, van Dam, Feiner, Hughes, *Computer Graphics*, §16.1.3): the color moves towards a cue color
//!   as the distance grows from `near` to `far`.
//! * The background, optionally: a gradient sky ([`Sky`], painted where no surface is).
//! * Alpha: the base color's alpha (factor × texture) is written to the color plane for a
//!   blended material (its coverage when composited, see [`crate::transparency`]) and as 1
//!   for the others, which glTF renders fully opaque ([`written_alpha`]).
//!
//! Everything takes *world-space barycentric weights* of a triangle, so both renderers
//! share it: the rasterizer's deferred pass gets them perspective-correctly from the pixel
//! (Heckbert & Moreton 1991; Blinn 1992), as does the ray caster's frame unless it casts
//! shadows or draws CSG solids; then it shades each hit from the hit's own weights.

use glam::{Affine3A, Mat3A, Vec2, Vec3, Vec3A, Vec4};
use serde::Serialize;
use sightline_scene::{AlphaMode, Material, Mesh};

pub use crate::color::to_rgba8;
use crate::sky::Sky;
use crate::texture::{self, Filter, Wrap};

/// How surfaces are lit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum ShadingMode {
    /// No shading pass: only depth and IDs are produced (the fastest path).
    None,
    /// One intensity per triangle from its face normal.
    #[default]
    Flat,
    /// Intensities lit at the vertices and interpolated.
    Gouraud,
    /// Normals interpolated and lit per pixel.
    PerPixel,
}

/// Depth cueing: color fades to `color` between `near` and `far` (distance from the eye).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DepthCue {
    /// Distance where fading starts.
    pub near: f32,
    /// Distance where only the cue color is left.
    pub far: f32,
    /// The cue color (linear RGB in [0, 1]).
    pub color: [f32; 3],
}

/// Shading parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ShadeOptions {
    /// Lighting model.
    pub mode: ShadingMode,
    /// Unit vector from surfaces towards the light (world space).
    pub light_dir: Vec3,
    /// Ambient intensity.
    pub ambient: f32,
    /// Diffuse intensity.
    pub diffuse: f32,
    /// Light both sides of a surface (normals are turned towards the viewer).
    pub two_sided: bool,
    /// Texture filter.
    pub filter: Filter,
    /// Texture addressing.
    pub wrap: Wrap,
    /// Perspective-correct attribute interpolation (off: affine in screen space, to show
    /// why it is needed). Ray-cast hits shaded one by one (with shadows or CSG solids)
    /// always use their exact weights.
    pub perspective_correct: bool,
    /// Optional depth cueing.
    pub depth_cue: Option<DepthCue>,
    /// The background: a gradient sky where no surface is drawn (`None`: the flat
    /// background color). Changes colors only; IDs and depth stay.
    pub sky: Option<Sky>,
}

impl Default for ShadeOptions {
    /// Flat Lambert, light from (0.35, 0.8, −0.5), 0.2 ambient + 0.8 diffuse: the shading of
    /// the llvmpipe (Mesa) reference renderer the tests compare against.
    fn default() -> Self {
        Self {
            mode: ShadingMode::Flat,
            light_dir: Vec3::new(0.35, 0.8, -0.5).normalize(),
            ambient: 0.2,
            diffuse: 0.8,
            two_sided: true,
            filter: Filter::Bilinear,
            wrap: Wrap::Repeat,
            perspective_correct: true,
            depth_cue: None,
            sky: None,
        }
    }
}

impl ShadeOptions {
    /// Unlit: color = base color × texture (ambient 1, diffuse 0).
    pub fn unlit() -> Self {
        Self { ambient: 1.0, diffuse: 0.0, ..Self::default() }
    }

    /// The look of pictures: a lower sun from the sky's bright side, more ambient light (the
    /// sides in shade keep their color), in front of the default [`Sky`].
    pub fn picture() -> Self {
        Self {
            light_dir: Vec3::new(0.35, 0.62, 0.70).normalize(),
            ambient: 0.32,
            diffuse: 0.78,
            sky: Some(Sky::default()),
            ..Self::default()
        }
    }
}

/// Lambert intensity for a unit normal.
#[inline]
pub fn lambert(normal: Vec3, opts: &ShadeOptions) -> f32 {
    opts.ambient + opts.diffuse * normal.dot(opts.light_dir).max(0.0)
}

/// The material's base color at `uv` (texture × factor), RGBA in [0, 1].
#[inline]
pub fn base_color(material: &Material, uv: Option<Vec2>, opts: &ShadeOptions) -> Vec4 {
    let f = Vec4::from(material.base_color);
    match (&material.base_color_texture, uv) {
        (Some(t), Some(uv)) => f * texture::sample(t, uv, opts.filter, opts.wrap),
        _ => f,
    }
}

/// The alpha a surface of `material` with base alpha `a` writes to the color plane: `a`
/// for a blended material (its coverage when composited), 1 for the others (glTF: an
/// `OPAQUE` or `MASK` surface renders fully opaque, whatever its alpha).
#[inline]
pub fn written_alpha(material: &Material, a: f32) -> f32 {
    if material.alpha_mode == AlphaMode::Blend {
        a
    } else {
        1.0
    }
}

/// Applies depth cueing (if on) at `distance` and converts to RGBA8.
#[inline]
pub fn finish(color: Vec4, distance: f32, opts: &ShadeOptions) -> [u8; 4] {
    let mut c = color;
    if let Some(q) = &opts.depth_cue {
        let span = (q.far - q.near).max(f32::MIN_POSITIVE);
        let f = ((distance - q.near) / span).clamp(0.0, 1.0);
        let f = if f.is_nan() { 0.0 } else { f };
        let cue = Vec4::new(q.color[0], q.color[1], q.color[2], c.w);
        c = c.lerp(cue, f);
    }
    to_rgba8(c)
}

/// Shades one surface point: Lambert with `normal` (turned towards `view_dir`, the
/// direction to the eye, when two-sided), base color from `material` and `uv`, depth cueing
/// at `distance`.
pub fn shade(
    material: &Material,
    normal: Vec3,
    uv: Option<Vec2>,
    view_dir: Vec3,
    distance: f32,
    opts: &ShadeOptions,
) -> [u8; 4] {
    let mut n = normal.normalize_or_zero();
    if opts.two_sided && n.dot(view_dir) < 0.0 {
        n = -n;
    }
    let base = base_color(material, uv, opts);
    let i = lambert(n, opts);
    finish(lit(material, base, i), distance, opts)
}

/// The color of a surface of `material` with base color `base` under light intensity `i`:
/// `base · i + emissive`, with the alpha [`written_alpha`] gives.
#[inline]
pub fn lit(material: &Material, base: Vec4, i: f32) -> Vec4 {
    (base.truncate() * i + Vec3::from(material.emissive)).extend(written_alpha(material, base.w))
}

/// What one instance contributes to shading: its transforms and material.
#[derive(Debug, Clone, Copy)]
pub struct InstanceShading<'a> {
    /// `world_from_local`.
    pub world_from_local: Affine3A,
    /// Inverse transpose of the linear part (for normals).
    pub normal_from_local: Mat3A,
    /// The resolved material.
    pub material: &'a Material,
}

impl<'a> InstanceShading<'a> {
    /// Prepares an instance (a singular matrix gives zero normals, shaded as ambient).
    pub fn new(world_from_local: Affine3A, material: &'a Material) -> Self {
        let m = world_from_local.matrix3;
        let det = m.determinant();
        let normal_from_local = if det.is_finite() && det != 0.0 { m.inverse().transpose() } else { Mat3A::ZERO };
        Self { world_from_local, normal_from_local, material }
    }
}

/// Whether every triangle of `mesh` drawn with `material` has one color at every point:
/// flat shading, no texture, no depth cueing. [`flat_color`] gives that color.
pub fn is_constant(material: &Material, mesh: &Mesh, opts: &ShadeOptions) -> bool {
    let textured = mesh.uvs().is_some() && material.base_color_texture.is_some();
    opts.mode == ShadingMode::Flat && !textured && opts.depth_cue.is_none()
}

/// The color of triangle `tri` when it is the same at every point (flat shading without
/// texture or depth cueing), else `None`. Cheaper than a [`TriangleShader`]: the face
/// normal is taken in local space and carried to world space by the normal matrix, and it
/// comes with the first corner from the mesh's face record ([`Mesh::faces`]), one load
/// instead of the indices and then the corners (two dependent cache misses in a big scene).
pub fn flat_color(inst: &InstanceShading, mesh: &Mesh, tri: usize, eye: Vec3, opts: &ShadeOptions) -> Option<[u8; 4]> {
    if !is_constant(inst.material, mesh, opts) || tri >= mesh.triangle_count() {
        return None;
    }
    let face = &mesh.faces()[tri];
    let (n_local, p0) = (Vec3A::from(face.normal), Vec3A::from(face.corner));
    let n = inst.normal_from_local * n_local;
    let len2 = n.length_squared();
    // cos(n, l), with n turned towards the eye when two-sided (sign of n·(eye − p0)).
    let mut ndl = if len2 > 0.0 && len2.is_finite() { n.dot(opts.light_dir.into()) / len2.sqrt() } else { 0.0 };
    if opts.two_sided && n.dot(Vec3A::from(eye) - inst.world_from_local.transform_point3a(p0)) < 0.0 {
        ndl = -ndl;
    }
    let i = opts.ambient + opts.diffuse * ndl.max(0.0);
    let b = base_color(inst.material, None, opts);
    Some(to_rgba8(lit(inst.material, b, i)))
}

/// Everything needed to shade points of one triangle from barycentric weights, prepared
/// once per triangle.
#[derive(Debug, Clone, Copy)]
pub struct TriangleShader<'a> {
    material: &'a Material,
    world: [Vec3A; 3],
    normals: [Vec3A; 3],
    uvs: Option<[Vec2; 3]>,
    /// Gouraud: lit vertex intensities.
    intensity: [f32; 3],
    /// Constant result (flat, untextured, no cueing).
    constant: Option<[u8; 4]>,
    eye: Vec3A,
    flip: bool,
}

impl<'a> TriangleShader<'a> {
    /// Prepares triangle `tri` of `mesh` drawn by `inst`, seen from `eye`. An out-of-range
    /// triangle index gives a shader of the material's color.
    pub fn new(inst: &InstanceShading<'a>, mesh: &Mesh, tri: usize, eye: Vec3, opts: &ShadeOptions) -> Self {
        let eye = Vec3A::from(eye);
        let idx = if tri < mesh.triangle_count() { mesh.triangle(tri).map(|i| i as usize) } else { [0; 3] };
        let pos = mesh.positions();
        let valid = tri < mesh.triangle_count();
        let world =
            idx.map(|i| if valid { inst.world_from_local.transform_point3a(pos[i].into()) } else { Vec3A::ZERO });
        let face = (world[1] - world[0]).cross(world[2] - world[0]).normalize_or_zero();
        let centroid = (world[0] + world[1] + world[2]) / 3.0;
        // Two-sided: turn the surface towards the viewer (decided once per triangle).
        let flip = opts.two_sided && face.dot(eye - centroid) < 0.0;
        let face = if flip { -face } else { face };
        if let Some(c) = flat_color(inst, mesh, tri, eye.into(), opts) {
            // The common case: one color for the whole triangle (same as the rasterizer's).
            return Self {
                material: inst.material,
                world,
                normals: [face; 3],
                uvs: None,
                intensity: [0.0; 3],
                constant: Some(c),
                eye,
                flip,
            };
        }
        let normals = match (opts.mode, mesh.normals()) {
            (ShadingMode::Gouraud | ShadingMode::PerPixel, Some(n)) if valid => idx.map(|i| {
                let v = (inst.normal_from_local * Vec3A::from(n[i])).normalize_or_zero();
                if flip {
                    -v
                } else {
                    v
                }
            }),
            _ => [face; 3],
        };
        let uvs = match (mesh.uvs(), &inst.material.base_color_texture) {
            (Some(uv), Some(_)) if valid => Some(idx.map(|i| uv[i])),
            _ => None,
        };
        let intensity = normals.map(|n| lambert(n.into(), opts));
        let constant = None;
        Self { material: inst.material, world, normals, uvs, intensity, constant, eye, flip }
    }

    /// The color of every point, when it does not vary over the triangle (flat shading
    /// without texture or depth cueing).
    #[inline]
    pub fn constant(&self) -> Option<[u8; 4]> {
        self.constant
    }

    /// True when the triangle was turned around to face the viewer.
    pub fn flipped(&self) -> bool {
        self.flip
    }

    /// The alpha at world-space barycentric weights `b`: the base color factor's alpha times
    /// the texture's there (what a material's [`AlphaMode`]
    /// judges), before lighting and quantization.
    #[inline]
    pub fn alpha(&self, b: Vec3, opts: &ShadeOptions) -> f32 {
        match self.uvs {
            Some(t) => base_color(self.material, Some(t[0] * b.x + t[1] * b.y + t[2] * b.z), opts).w,
            None => base_color(self.material, None, opts).w,
        }
    }

    /// The color at world-space barycentric weights `b` (b.x + b.y + b.z = 1).
    #[inline]
    pub fn shade(&self, b: Vec3, opts: &ShadeOptions) -> [u8; 4] {
        if let Some(c) = self.constant {
            return c;
        }
        let uv = self.uvs.map(|t| t[0] * b.x + t[1] * b.y + t[2] * b.z);
        let base = base_color(self.material, uv, opts);
        let i = match opts.mode {
            ShadingMode::Gouraud => self.intensity[0] * b.x + self.intensity[1] * b.y + self.intensity[2] * b.z,
            ShadingMode::PerPixel => {
                let n = self.normals[0] * b.x + self.normals[1] * b.y + self.normals[2] * b.z;
                lambert(n.normalize_or_zero().into(), opts)
            }
            _ => self.intensity[0],
        };
        let distance = if opts.depth_cue.is_some() {
            let p = self.world[0] * b.x + self.world[1] * b.y + self.world[2] * b.z;
            (p - self.eye).length()
        } else {
            0.0
        };
        finish(lit(self.material, base, i), distance, opts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lambert_and_two_sided() {
        let o = ShadeOptions::default();
        let m = Material::color("w", [1.0, 1.0, 1.0]);
        let lit = shade(&m, o.light_dir, None, o.light_dir, 0.0, &o);
        assert_eq!(lit, [255, 255, 255, 255]);
        // Facing away from the light: ambient only.
        let dark = shade(&m, -o.light_dir, None, -o.light_dir, 0.0, &o);
        assert_eq!(dark[0], (0.2f32 * 255.0 + 0.5) as u8);
        // Seen from behind, two-sided lighting turns the normal around.
        let back = shade(&m, -o.light_dir, None, o.light_dir, 0.0, &o);
        assert_eq!(back, lit);
    }

    #[test]
    fn depth_cue_fades_with_distance() {
        let o = ShadeOptions {
            depth_cue: Some(DepthCue { near: 10.0, far: 20.0, color: [0.0, 0.0, 0.0] }),
            ..ShadeOptions::unlit()
        };
        let m = Material::color("w", [1.0, 1.0, 1.0]);
        let at = |d| shade(&m, Vec3::Y, None, Vec3::Y, d, &o)[0];
        assert_eq!(at(5.0), 255);
        assert_eq!(at(15.0), 128);
        assert_eq!(at(25.0), 0);
    }

    #[test]
    fn gouraud_interpolates_vertex_light() {
        let mesh = sightline_scene::shapes::ground_quad("g", 1).unwrap();
        let m = Material::color("w", [1.0, 1.0, 1.0]);
        let inst = InstanceShading::new(Affine3A::IDENTITY, &m);
        let o = ShadeOptions { mode: ShadingMode::Gouraud, light_dir: Vec3::Y, ..ShadeOptions::default() };
        let s = TriangleShader::new(&inst, &mesh, 0, Vec3::new(0.0, 5.0, 0.0), &o);
        assert_eq!(s.shade(Vec3::splat(1.0 / 3.0), &o), [255, 255, 255, 255]);
        assert!(!s.flipped());
        let below = TriangleShader::new(&inst, &mesh, 0, Vec3::new(0.0, -5.0, 0.0), &o);
        assert!(below.flipped());
        assert_eq!(below.shade(Vec3::X, &o)[0], (0.2f32 * 255.0 + 0.5) as u8);
    }
}

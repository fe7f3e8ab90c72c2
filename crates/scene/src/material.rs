//! Materials: a base color factor and an optional base color texture (decoded RGBA8).
//!
//! A material set on an inner node applies to its whole subtree unless a descendant sets its
//! own; [`Scene::instances`](crate::Scene::instances) resolves the inherited material of every
//! drawn node.

use std::sync::Arc;

/// A decoded RGBA8 texture, rows from the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// `width * height * 4` bytes, row-major, row 0 at the top (v = 0).
    pub rgba: Vec<u8>,
}

impl Texture {
    /// A texture from raw RGBA8 data; `None` when the sizes do not match or are zero.
    pub fn new(width: u32, height: u32, rgba: Vec<u8>) -> Option<Self> {
        (width > 0 && height > 0 && rgba.len() == width as usize * height as usize * 4).then_some(Self {
            width,
            height,
            rgba,
        })
    }

    /// The texel at integer coordinates (clamped to the image).
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> [u8; 4] {
        let x = x.min(self.width - 1) as usize;
        let y = y.min(self.height - 1) as usize;
        let i = (y * self.width as usize + x) * 4;
        [self.rgba[i], self.rgba[i + 1], self.rgba[i + 2], self.rgba[i + 3]]
    }
}

/// Surface appearance shared by any number of nodes.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// A name for messages and statistics.
    pub name: String,
    /// Linear RGBA multiplier (glTF `baseColorFactor`, OBJ `Kd`).
    pub base_color: [f32; 4],
    /// Optional base color texture, multiplied with `base_color`.
    pub base_color_texture: Option<Arc<Texture>>,
}

impl Default for Material {
    fn default() -> Self {
        Self { name: "default".into(), base_color: [0.8, 0.8, 0.8, 1.0], base_color_texture: None }
    }
}

impl Material {
    /// A plain colored material.
    pub fn color(name: impl Into<String>, rgb: [f32; 3]) -> Self {
        Self { name: name.into(), base_color: [rgb[0], rgb[1], rgb[2], 1.0], base_color_texture: None }
    }
}

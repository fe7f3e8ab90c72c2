//! Materials: a base color factor, an optional base color texture (decoded RGBA8), an
//! alpha mode and an emitted color.
//!
//! The alpha mode is glTF 2.0's (`material.alphaMode`, `alphaCutoff`; Khronos, glTF 2.0
//! specification, "Alpha Coverage"): the alpha of a surface point is the base color
//! factor's alpha times the base color texture's alpha there; `Opaque` ignores it, `Mask`
//! keeps the points whose alpha is at least the cutoff (and draws them opaque), `Blend`
//! composites the surface over what lies behind it.
//!
//! A material set on an inner node applies to its whole subtree unless a descendant sets its
//! own; [`Scene::instances`](crate::Scene::instances) resolves the inherited material of every
//! drawn node.

use std::sync::{Arc, LazyLock};

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
        let t = Self { width, height, rgba };
        t.is_well_formed().then_some(t)
    }

    /// Whether the sizes and the data agree (as [`Texture::new`] checks): the fields are
    /// public, so a texture made by hand may break it.
    pub fn is_well_formed(&self) -> bool {
        let bytes = (self.width as u64).checked_mul(self.height as u64).and_then(|n| n.checked_mul(4));
        self.width > 0 && self.height > 0 && bytes.is_some_and(|n| self.rgba.len() as u64 == n)
    }

    /// The texel at integer coordinates (clamped to the image); transparent black where a
    /// texture that is not well formed has no data.
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> [u8; 4] {
        let x = x.min(self.width.saturating_sub(1)) as usize;
        let y = y.min(self.height.saturating_sub(1)) as usize;
        let i = y.checked_mul(self.width as usize).and_then(|r| r.checked_add(x)?.checked_mul(4));
        match i.and_then(|i| self.rgba.get(i..i.checked_add(4)?)) {
            Some(&[r, g, b, a]) => [r, g, b, a],
            _ => [0; 4],
        }
    }
}

/// The alpha cutoff of a [`AlphaMode::Mask`] material when none is given (glTF's default).
pub const DEFAULT_ALPHA_CUTOFF: f32 = 0.5;

/// How a material's alpha (base color factor alpha × base color texture alpha) is used:
/// glTF 2.0's `alphaMode`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum AlphaMode {
    /// Alpha is ignored: the surface is drawn fully opaque (the default).
    #[default]
    Opaque,
    /// A point is drawn, fully opaque, where its alpha is at least `cutoff`, and is not
    /// drawn at all (no depth, no triangle ID) elsewhere. A NaN cutoff draws nothing; loaders
    /// never produce one (they replace bad values by [`DEFAULT_ALPHA_CUTOFF`]).
    Mask {
        /// The alpha a point needs to be drawn.
        cutoff: f32,
    },
    /// The surface is composited over what lies behind it with its alpha as coverage
    /// (Porter & Duff's "over").
    Blend,
}

impl AlphaMode {
    /// `Mask` with glTF's default cutoff, 0.5.
    pub fn mask() -> Self {
        AlphaMode::Mask { cutoff: DEFAULT_ALPHA_CUTOFF }
    }

    /// True for [`AlphaMode::Opaque`].
    pub fn is_opaque(self) -> bool {
        self == AlphaMode::Opaque
    }

    /// The name glTF uses: `OPAQUE`, `MASK` or `BLEND`.
    pub fn gltf_name(self) -> &'static str {
        match self {
            AlphaMode::Opaque => "OPAQUE",
            AlphaMode::Mask { .. } => "MASK",
            AlphaMode::Blend => "BLEND",
        }
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
    /// What the alpha of `base_color` × texture means: opaque, a cutout mask or blending.
    pub alpha_mode: AlphaMode,
    /// Light the surface gives off itself, linear RGB added after lighting (glTF
    /// `emissiveFactor`): a lit window stays bright on the side the sun does not reach.
    pub emissive: [f32; 3],
}

impl Default for Material {
    fn default() -> Self {
        Self {
            name: "default".into(),
            base_color: [0.8, 0.8, 0.8, 1.0],
            base_color_texture: None,
            alpha_mode: AlphaMode::Opaque,
            emissive: [0.0; 3],
        }
    }
}

/// The one [`Material::default`] that [`Material::fallback`] lends.
static FALLBACK: LazyLock<Material> = LazyLock::new(Material::default);

impl Material {
    /// The material of surfaces that have none (no own or inherited material, or a stale
    /// handle): [`Material::default`], made once and shared.
    pub fn fallback() -> &'static Material {
        &FALLBACK
    }

    /// A plain colored material.
    pub fn color(name: impl Into<String>, rgb: [f32; 3]) -> Self {
        Self { name: name.into(), base_color: [rgb[0], rgb[1], rgb[2], 1.0], ..Self::default() }
    }

    /// A plain translucent material: color `rgb` with alpha `alpha`, blended
    /// ([`AlphaMode::Blend`]).
    pub fn translucent(name: impl Into<String>, rgb: [f32; 3], alpha: f32) -> Self {
        Self {
            name: name.into(),
            base_color: [rgb[0], rgb[1], rgb[2], alpha],
            alpha_mode: AlphaMode::Blend,
            ..Self::default()
        }
    }

    /// This material giving off light `rgb` (see [`Material::emissive`]).
    pub fn with_emissive(mut self, rgb: [f32; 3]) -> Self {
        self.emissive = rgb;
        self
    }

    /// This material with alpha mode `mode`.
    pub fn with_alpha_mode(mut self, mode: AlphaMode) -> Self {
        self.alpha_mode = mode;
        self
    }
}

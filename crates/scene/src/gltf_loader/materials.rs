//! glTF materials: `pbrMetallicRoughness.baseColorFactor` and `baseColorTexture` (PNG or JPEG
//! images, decoded once each, failures included), `alphaMode` and `alphaCutoff`, and
//! `emissiveFactor`; the glTF 2.0 specification, "Materials".

use super::*;

impl Loader<'_> {
    pub(super) fn material(&mut self, i: usize) -> std::result::Result<MaterialId, String> {
        if let Some(Some(id)) = self.materials.get(i) {
            return Ok(*id);
        }
        let mat = self.root.materials.get(i).ok_or_else(|| format!("material {i} does not exist"))?;
        let label = label("material", i, mat.name.as_deref());
        let pbr = &mat.pbr_metallic_roughness;
        let mut base_color = pbr.base_color_factor.0;
        if !base_color.iter().all(|c| c.is_finite()) {
            self.scene.warnings.push(format!("{label}: baseColorFactor {base_color:?} is not finite; using white"));
            base_color = [1.0; 4];
        }
        let mut texture = None;
        if let Some(info) = &pbr.base_color_texture {
            match self.base_color_texture(info) {
                Ok(t) => texture = Some(t),
                Err(AssetError::Refused(e)) => return Err(format!("{label}: base color texture: {e}")),
                Err(AssetError::Unavailable(e)) => self
                    .scene
                    .warnings
                    .push(format!("{label}: base color texture: {e}; using the base color factor alone")),
            }
        }
        let alpha_mode = self.alpha_mode(mat, &label);
        let id = self.scene.add_material(Material {
            name: mat.name.clone().unwrap_or_else(|| format!("material {i}")),
            base_color,
            base_color_texture: texture,
            alpha_mode,
            emissive: emissive(mat),
        });
        if let Some(slot) = self.materials.get_mut(i) {
            *slot = Some(id);
        }
        Ok(id)
    }

    /// The material's `alphaMode` and `alphaCutoff`: an unknown mode is a warning (opaque),
    /// a cutoff that is negative or not finite a warning (0.5); the cutoff of a mode other
    /// than `MASK` is ignored, as the specification says.
    fn alpha_mode(&mut self, mat: &json::Material, label: &str) -> AlphaMode {
        match mat.alpha_mode {
            Checked::Valid(json::material::AlphaMode::Opaque) => AlphaMode::Opaque,
            Checked::Valid(json::material::AlphaMode::Blend) => AlphaMode::Blend,
            Checked::Valid(json::material::AlphaMode::Mask) => {
                let cutoff = mat.alpha_cutoff.map_or(DEFAULT_ALPHA_CUTOFF, |c| c.0);
                if cutoff.is_finite() && cutoff >= 0.0 {
                    AlphaMode::Mask { cutoff }
                } else {
                    self.scene.warnings.push(format!(
                        "{label}: alphaCutoff {cutoff} is not a number >= 0; using {DEFAULT_ALPHA_CUTOFF}"
                    ));
                    AlphaMode::mask()
                }
            }
            Checked::Invalid => {
                self.scene.warnings.push(format!("{label}: unknown alphaMode; drawing it opaque"));
                AlphaMode::Opaque
            }
        }
    }

    fn base_color_texture(&mut self, info: &json::texture::Info) -> std::result::Result<Arc<Texture>, AssetError> {
        let bad = AssetError::Unavailable;
        if info.tex_coord != 0 {
            return Err(bad(format!("it uses TEXCOORD_{}, only TEXCOORD_0 is loaded", info.tex_coord)));
        }
        let t = info.index.value();
        let tex = self.root.textures.get(t).ok_or_else(|| bad(format!("texture {t} does not exist")))?;
        let img = tex.source.value();
        if let Some(Some(done)) = self.images.get(img) {
            return done.clone();
        }
        let done = self.decode_image(t, img);
        if let Some(slot) = self.images.get_mut(img) {
            *slot = Some(done.clone());
        }
        done
    }

    /// Reads and decodes image `img` (named by texture `t`), its pixels charged against
    /// [`LoadOptions::max_decoded_bytes`] before they are decoded: many images (or materials)
    /// can name one small file that decodes to a gigabyte.
    fn decode_image(&self, t: usize, img: usize) -> std::result::Result<Arc<Texture>, AssetError> {
        let bad = AssetError::Unavailable;
        let image = self
            .root
            .images
            .get(img)
            .ok_or_else(|| bad(format!("texture {t} refers to image {img}, which does not exist")))?;
        let label = match &image.uri {
            Some(uri) => format!("image {img} ('{}')", short_uri(uri)),
            None => label("image", img, image.name.as_deref()),
        };
        let from_uri;
        let bytes: &[u8] = match (&image.uri, image.buffer_view) {
            (Some(uri), _) => {
                from_uri = read_uri(uri, self.assets, u64::MAX, MAX_IMAGE_FILE).map_err(|e| e.context(&label))?;
                from_uri.bytes()
            }
            (None, Some(v)) => self.view_bytes(v.value()).map_err(|e| e.context(&label))?.0,
            (None, None) => return Err(bad(format!("{label} has neither a uri nor a buffer view"))),
        };
        Ok(Arc::new(decode_for_load(bytes, self.assets).map_err(|e| e.context(&label))?))
    }
}

/// Decodes a texture for a load: its texels are charged against
/// [`LoadOptions::max_decoded_bytes`] before it is decoded. An image past that cap, too
/// large, or that cannot be decoded is unavailable: the material keeps its color and the
/// load goes on with a warning (a texture is never needed to draw), without decoding it.
/// The caller names the image in the message.
pub(crate) fn decode_for_load(bytes: &[u8], assets: &AssetReader) -> std::result::Result<Texture, AssetError> {
    let (w, h) = texture_size(bytes).map_err(AssetError::Unavailable)?;
    if w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE {
        return Err(AssetError::Unavailable(format!("{w} × {h} texels, more than {MAX_TEXTURE_SIDE} a side")));
    }
    let texels = w as u64 * h as u64 * 4;
    assets.charge_decoded(texels, format_args!("decoding its {w} × {h} texels")).map_err(AssetError::Unavailable)?;
    decode_texture(bytes).map_err(AssetError::Unavailable)
}

/// Largest texture side accepted, in texels.
const MAX_TEXTURE_SIDE: u32 = 16384;

/// A reader of a PNG or JPEG image (format sniffed from the bytes).
fn image_reader(bytes: &[u8]) -> std::result::Result<image::ImageReader<std::io::Cursor<&[u8]>>, String> {
    let reader =
        image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format().map_err(|e| e.to_string())?;
    match reader.format() {
        Some(_) => Ok(reader),
        None => Err("unknown image format (PNG and JPEG are supported)".into()),
    }
}

/// The width and height of a PNG or JPEG image, from its header (nothing decoded).
fn texture_size(bytes: &[u8]) -> std::result::Result<(u32, u32), String> {
    image_reader(bytes)?.into_dimensions().map_err(|e| format!("cannot decode: {e}"))
}

/// Decodes a PNG or JPEG image (format sniffed from the bytes) into an RGBA8 [`Texture`].
fn decode_texture(bytes: &[u8]) -> std::result::Result<Texture, String> {
    let mut reader = image_reader(bytes)?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_SIDE);
    limits.max_image_height = Some(MAX_TEXTURE_SIDE);
    limits.max_alloc = Some(1 << 30);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| format!("cannot decode: {e}"))?;
    let rgba = img.to_rgba8();
    let (w, h) = rgba.dimensions();
    Texture::new(w, h, rgba.into_raw()).ok_or_else(|| format!("bad image size {w}x{h}"))
}

/// The material's `emissiveFactor` (glTF: linear RGB, default black); a component that is
/// negative or not finite counts as 0.
fn emissive(mat: &json::Material) -> [f32; 3] {
    mat.emissive_factor.0.map(|c| if c.is_finite() { c.max(0.0) } else { 0.0 })
}

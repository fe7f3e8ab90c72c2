//! glTF 2.0 loader: `.gltf` (external `.bin` files or base64 data URIs) and `.glb`.
//!
//! What is loaded:
//!
//! * The node hierarchy of the default scene (else scene 0, else every node that is nobody's
//!   child), with TRS or matrix transforms. Each glTF node becomes one scene node. A glTF mesh
//!   with one drawable primitive is drawn by the node itself; with several, by one child node
//!   per primitive. Converted meshes are cached per (mesh, primitive), so glTF instancing stays
//!   instancing in the mesh store.
//! * Primitives of mode `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN` (strips and fans are
//!   converted to triangle lists with the winding kept); points and lines are skipped and
//!   counted in a warning. Attributes `POSITION`, `NORMAL`, `TEXCOORD_0` (float, or integer
//!   types as `KHR_mesh_quantization` allows), indices of u8/u16/u32 or none, sparse accessors.
//! * Materials: `pbrMetallicRoughness.baseColorFactor` and `baseColorTexture` (PNG or JPEG,
//!   decoded to RGBA8 with the `image` crate).
//! * Perspective and orthographic cameras, as [`SceneCamera`]s on their nodes.
//!
//! Skins, morph targets, animations and the other material channels are ignored.
//!
//! External files (buffer and image URIs; glTF 2.0 specification, sections "URIs", "Buffers
//! and Buffer Views" and "Images") are read under the rules of [`crate::assets`]: inside the glTF file's folder (or an allowed root), regular files
//! only, each read once and no further than needed, within a total. A buffer is read only when
//! an accessor or image that the scene uses needs it, and no more than its `byteLength`.
//!
//! Errors ([`Error::Load`], naming the file and the problem): unreadable file, wrong magic,
//! truncated GLB, invalid JSON, missing or short buffers that the scene uses, accessors
//! reading past their buffer views, indices out of range, NaN/infinite transforms, a node graph
//! that is not a forest (a node reached twice, a cycle), a required extension this loader does
//! not support, a buffer or image URI that the rules above refuse (outside the folder, not a
//! regular file, over the total).
//! Warnings (in [`Scene::warnings`], the scene still loads): a missing or undecodable
//! texture (the material keeps its base color factor), skipped point/line primitives, used but
//! not required unknown extensions, unusable cameras.
//!
//! The loader does its own bounds-checked parsing of the GLB container, buffers and accessors
//! on top of `gltf::json` (serde structs), so no input makes it panic.

use std::cell::OnceCell;
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{Mat4, Quat, Vec2, Vec3};
use gltf::json;
use json::accessor::{ComponentType, Type};
use json::mesh::{Mode, Semantic};
use json::validation::Checked;

use crate::assets::{AssetError, AssetReader};
use crate::{
    Error, LoadOptions, Material, MaterialId, Mesh, MeshId, NodeDesc, NodeId, Projection, Result, Scene, SceneCamera,
    Texture, Transform,
};

/// glTF extensions this loader honours, so a file may list them in `extensionsRequired`.
pub const SUPPORTED_EXTENSIONS: &[&str] = &["KHR_mesh_quantization"];

/// Far plane used for a perspective camera without `zfar` (an infinite projection in glTF):
/// `max(DEFAULT_FAR, 1e4 * znear)`.
pub const DEFAULT_FAR: f32 = 1.0e4;

/// Aspect ratio used for a perspective camera without `aspectRatio`.
pub const DEFAULT_ASPECT: f32 = 1.0;

/// Loads a `.gltf` or `.glb` file; external buffers and images are found next to it, with the
/// default [`LoadOptions`] (files inside its folder only).
///
/// The returned scene's world transforms are not yet propagated (call
/// [`Scene::update_transforms`], or use [`crate::load`], which does).
pub fn load_gltf(path: &Path) -> Result<Scene> {
    load_gltf_with(path, &LoadOptions::default())
}

/// [`load_gltf`] with options: other folders external files may come from, a read cap.
pub fn load_gltf_with(path: &Path, options: &LoadOptions) -> Result<Scene> {
    let assets = AssetReader::new(path, options).map_err(|e| Error::load(path, e))?;
    let bytes = assets.read_main().map_err(|e| Error::load(path, e))?;
    load_with_reader(&bytes, path, &assets)
}

/// Loads glTF or GLB from memory. `path` names the file in messages, decides whether the bytes
/// must be GLB (extension `.glb`), and its folder resolves relative URIs (under the default
/// [`LoadOptions`]).
pub fn load_gltf_bytes(bytes: &[u8], path: &Path) -> Result<Scene> {
    load_gltf_bytes_with(bytes, path, &LoadOptions::default())
}

/// [`load_gltf_bytes`] with options.
pub fn load_gltf_bytes_with(bytes: &[u8], path: &Path, options: &LoadOptions) -> Result<Scene> {
    let assets = AssetReader::new(path, options).map_err(|e| Error::load(path, e))?;
    load_with_reader(bytes, path, &assets)
}

fn load_with_reader(bytes: &[u8], path: &Path, assets: &AssetReader) -> Result<Scene> {
    let fail = |why: String| Error::load(path, why);
    let is_glb_name = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    let (json_bytes, bin) = if bytes.starts_with(b"glTF") {
        split_glb(bytes).map_err(fail)?
    } else if is_glb_name && b"glTF".starts_with(bytes) {
        return Err(fail(format!("truncated: {} bytes is too short for a GLB header", bytes.len())));
    } else if is_glb_name {
        let head = bytes.get(..4).unwrap_or(bytes);
        return Err(fail(format!(
            "wrong magic: a .glb file must start with \"glTF\", this one starts with {:?}",
            String::from_utf8_lossy(head)
        )));
    } else {
        (bytes, None)
    };
    let root = json::Root::from_slice(json_bytes).map_err(|e| fail(format!("invalid glTF JSON: {e}")))?;
    if !root.asset.version.starts_with("2.") {
        return Err(fail(format!("unsupported glTF version '{}' (expected 2.x)", root.asset.version)));
    }
    let mut warnings = Vec::new();
    for ext in &root.extensions_required {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            return Err(fail(format!("the file requires extension '{ext}', which this loader does not support")));
        }
    }
    for ext in &root.extensions_used {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            warnings.push(format!("ignoring unsupported glTF extension '{ext}'"));
        }
    }
    // The bytes wanted of each external file, by URI: the largest byteLength of the buffers
    // that name it and have views, so a file named by many buffers is read once.
    let mut uri_want: HashMap<&str, u64> = HashMap::new();
    let mut viewed = vec![false; root.buffers.len()];
    for v in &root.buffer_views {
        if let Some(f) = viewed.get_mut(v.buffer.value()) {
            *f = true;
        }
    }
    for (b, _) in root.buffers.iter().zip(&viewed).filter(|(_, &v)| v) {
        if let Some(uri) = &b.uri {
            let w = uri_want.entry(uri.as_str()).or_insert(0);
            *w = (*w).max(b.byte_length.0);
        }
    }
    let mut loader = Loader {
        root: &root,
        bin,
        bin_owner: root.buffers.iter().position(|b| b.uri.is_none()),
        buffers: root.buffers.iter().map(|_| OnceCell::new()).collect(),
        assets,
        uri_want,
        scene: Scene::new(),
        meshes: HashMap::new(),
        materials: vec![None; root.materials.len()],
        images: vec![None; root.images.len()],
        default_material: None,
        skipped: Vec::new(),
    };
    loader.scene.warnings = warnings;
    loader.build().map_err(fail)?;
    let mut scene = loader.scene;
    let skipped = loader.skipped;
    if !skipped.is_empty() {
        let mut list = skipped.iter().take(5).cloned().collect::<Vec<_>>().join(", ");
        if skipped.len() > 5 {
            list.push_str(", ...");
        }
        scene
            .warnings
            .push(format!("skipped {} point/line primitive(s), only triangles are drawn: {list}", skipped.len()));
    }
    for w in &mut scene.warnings {
        *w = format!("{}: {w}", path.display());
    }
    Ok(scene)
}

// ---- container and buffers ----------------------------------------------------------------

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    let s = b.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes(s.try_into().ok()?))
}

/// Splits a GLB file into its JSON chunk and optional BIN chunk.
fn split_glb(b: &[u8]) -> std::result::Result<(&[u8], Option<&[u8]>), String> {
    const JSON: u32 = 0x4E4F_534A;
    const BIN: u32 = 0x004E_4942;
    if b.len() < 20 {
        return Err(format!("truncated: {} bytes is too short for a GLB header and a JSON chunk", b.len()));
    }
    let version = u32_at(b, 4).unwrap_or(0);
    if version != 2 {
        return Err(format!("unsupported GLB container version {version} (expected 2)"));
    }
    let length = u32_at(b, 8).unwrap_or(0) as usize;
    if length > b.len() {
        return Err(format!("truncated: the GLB header says {length} bytes but the file has {}", b.len()));
    }
    let b = b.get(..length).unwrap_or(b);
    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    let mut index = 0;
    while at < b.len() {
        let (Some(len), Some(ty)) = (u32_at(b, at), u32_at(b, at + 4)) else {
            return Err(format!("truncated: GLB chunk {index} has an incomplete header"));
        };
        let start = at + 8;
        let data = start.checked_add(len as usize).and_then(|end| b.get(start..end)).ok_or_else(|| {
            format!("truncated: GLB chunk {index} says {len} bytes but only {} remain", b.len().saturating_sub(start))
        })?;
        match (index, ty) {
            (0, JSON) => json = Some(data),
            (0, _) => return Err("the first GLB chunk is not the JSON chunk".into()),
            (_, BIN) if bin.is_none() => bin = Some(data),
            _ => {} // unknown chunks are skipped, as the spec asks
        }
        // Chunks are 4-byte aligned; a writer that forgot padding is tolerated.
        at = start + data.len();
        index += 1;
    }
    let json = json.ok_or("the GLB file has no JSON chunk")?;
    Ok((json, bin))
}

/// Largest external image file read, in bytes.
const MAX_IMAGE_FILE: u64 = 256 << 20;

/// A buffer's bytes: the GLB BIN chunk, a decoded data URI, or (a prefix of) a file.
enum BufferData<'a> {
    Borrowed(&'a [u8]),
    Owned(Vec<u8>),
    Shared(Arc<[u8]>, usize),
}

impl BufferData<'_> {
    fn bytes(&self) -> &[u8] {
        match self {
            BufferData::Borrowed(b) => b,
            BufferData::Owned(v) => v,
            BufferData::Shared(a, n) => a.get(..*n).unwrap_or(a),
        }
    }
}

/// Reads what a URI points to: a data URI (decoded), or a file relative to the glTF file's
/// folder, read under the rules of [`crate::assets`] (at most `want` bytes; a file over
/// `max_file` bytes is not read).
fn read_uri<'a>(
    uri: &str,
    assets: &AssetReader,
    want: u64,
    max_file: u64,
) -> std::result::Result<BufferData<'a>, AssetError> {
    let bad = |m: String| AssetError::Unavailable(m);
    if let Some(rest) = uri.strip_prefix("data:") {
        let (header, data) =
            rest.split_once(',').ok_or_else(|| bad("malformed data URI: no ',' before the data".into()))?;
        let bytes = if header.ends_with(";base64") { base64_decode(data).map_err(bad)? } else { percent_decode(data) };
        return Ok(BufferData::Owned(bytes));
    }
    let rel = uri.strip_prefix("file://").unwrap_or(uri);
    if let Some((scheme, _)) = rel.split_once("://") {
        return Err(bad(format!("unsupported URI scheme '{scheme}'")));
    }
    let rel = String::from_utf8(percent_decode(rel))
        .map_err(|_| bad("the URI is not valid UTF-8 after percent-decoding".to_string()))?;
    let file = assets.resolve(Path::new(&rel))?;
    let (bytes, _) = assets.read(&file, want, max_file)?;
    let n = usize::try_from(want).unwrap_or(usize::MAX).min(bytes.len());
    Ok(BufferData::Shared(bytes, n))
}

fn percent_decode(s: &str) -> Vec<u8> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        match (b[i], b.get(i + 1).copied(), b.get(i + 2).copied()) {
            (b'%', Some(h), Some(l)) if hex(h).is_some() && hex(l).is_some() => {
                out.push((hex(h).unwrap_or(0) * 16 + hex(l).unwrap_or(0)) as u8);
                i += 3;
            }
            (c, _, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    out
}

/// Standard (and URL-safe) base64 with optional padding; whitespace is ignored.
fn base64_decode(s: &str) -> std::result::Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for (i, c) in s.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return Err(format!("invalid base64 character at offset {i}")),
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// A URI shortened for messages (data URIs can be megabytes long).
fn short_uri(uri: &str) -> String {
    if uri.starts_with("data:") {
        "data URI".into()
    } else {
        uri.chars().take(120).collect()
    }
}

// ---- accessors ----------------------------------------------------------------------------

fn component_size(c: ComponentType) -> usize {
    match c {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

/// Reads one component as f64 (exact for every glTF component type).
fn read_component(b: &[u8], at: usize, c: ComponentType, normalized: bool) -> Option<f64> {
    let s = b.get(at..at.checked_add(component_size(c))?)?;
    let v = match c {
        ComponentType::I8 => {
            let v = s[0] as i8 as f64;
            if normalized {
                (v / 127.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U8 => s[0] as f64 / if normalized { 255.0 } else { 1.0 },
        ComponentType::I16 => {
            let v = i16::from_le_bytes([s[0], s[1]]) as f64;
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U16 => u16::from_le_bytes([s[0], s[1]]) as f64 / if normalized { 65535.0 } else { 1.0 },
        ComponentType::U32 => {
            u32::from_le_bytes([s[0], s[1], s[2], s[3]]) as f64 / if normalized { u32::MAX as f64 } else { 1.0 }
        }
        ComponentType::F32 => f32::from_le_bytes([s[0], s[1], s[2], s[3]]) as f64,
    };
    Some(v)
}

/// Accessors larger than this without buffer data (all zeros) are refused, so a bogus count
/// cannot allocate gigabytes.
const MAX_UNBACKED_ELEMENTS: u64 = 1 << 24;

impl<'a> Loader<'a> {
    /// Loads buffer `i` (called once per buffer, when a view of it is first read).
    fn load_buffer(&self, i: usize) -> std::result::Result<BufferData<'a>, AssetError> {
        let buf =
            self.root.buffers.get(i).ok_or_else(|| AssetError::Unavailable(format!("buffer {i} does not exist")))?;
        let (data, label) = match &buf.uri {
            None => match self.bin.filter(|_| self.bin_owner == Some(i)) {
                Some(b) => (BufferData::Borrowed(b), "GLB BIN chunk".to_string()),
                None => {
                    return Err(AssetError::Unavailable(format!(
                        "buffer {i} has no uri and there is no (unused) GLB BIN chunk for it"
                    )))
                }
            },
            Some(uri) => {
                let label = format!("'{}'", short_uri(uri));
                let want = self.uri_want.get(uri.as_str()).copied().unwrap_or(buf.byte_length.0);
                let data = read_uri(uri, self.assets, want, u64::MAX)
                    .map_err(|e| e.context(format!("buffer {i} ({label})")))?;
                (data, label)
            }
        };
        let len = data.bytes().len() as u64;
        if len < buf.byte_length.0 {
            return Err(AssetError::Unavailable(format!(
                "buffer {i} ({label}) is too short: {len} bytes, byteLength says {}",
                buf.byte_length.0
            )));
        }
        // A file read further for another buffer naming it is cut back to this one's length.
        Ok(match data {
            BufferData::Shared(a, _) => BufferData::Shared(a, buf.byte_length.0 as usize),
            other => other,
        })
    }

    /// The bytes of buffer view `v`, bounds-checked against its buffer (which is loaded now if
    /// it was not yet).
    fn view_bytes(&self, v: usize) -> std::result::Result<(&[u8], Option<usize>), AssetError> {
        let bad = AssetError::Unavailable;
        let view = self.root.buffer_views.get(v).ok_or_else(|| bad(format!("buffer view {v} does not exist")))?;
        let b = view.buffer.value();
        let cell = self
            .buffers
            .get(b)
            .ok_or_else(|| bad(format!("buffer view {v} refers to buffer {b}, which does not exist")))?;
        let data = cell.get_or_init(|| self.load_buffer(b)).as_ref().map_err(Clone::clone)?.bytes();
        let off = view.byte_offset.map_or(0, |o| o.0);
        let len = view.byte_length.0;
        let bytes = off
            .checked_add(len)
            .and_then(|end| data.get(usize::try_from(off).ok()?..usize::try_from(end).ok()?))
            .ok_or_else(|| {
                bad(format!(
                    "buffer view {v} (offset {off}, length {len}) reads past the end of buffer {b} ({} bytes)",
                    data.len()
                ))
            })?;
        Ok((bytes, view.byte_stride.map(|s| s.0)))
    }

    /// Reads accessor `i` as `count * dims` numbers (f64, converted per component type).
    fn read_accessor(
        &self,
        i: usize,
        want: &[Type],
        what: &str,
    ) -> std::result::Result<(Vec<f64>, ComponentType), String> {
        let a = self.root.accessors.get(i).ok_or_else(|| format!("{what} accessor {i} does not exist"))?;
        let ty = match a.type_ {
            Checked::Valid(t) if want.contains(&t) => t,
            Checked::Valid(t) => return Err(format!("{what} accessor {i} has type {t:?}, expected one of {want:?}")),
            Checked::Invalid => return Err(format!("{what} accessor {i} has an invalid type")),
        };
        let comp = match a.component_type {
            Checked::Valid(c) => c.0,
            Checked::Invalid => return Err(format!("{what} accessor {i} has an invalid component type")),
        };
        let dims = ty.multiplicity();
        let csize = component_size(comp);
        let elem = dims * csize;
        let count = a.count.0;
        let mut out;
        match a.buffer_view {
            None => {
                if count > MAX_UNBACKED_ELEMENTS {
                    return Err(format!("{what} accessor {i} has no buffer view but {count} elements"));
                }
                out = vec![0.0; count as usize * dims];
            }
            Some(v) => {
                let v = v.value();
                let (bytes, stride) = self.view_bytes(v)?;
                let stride = stride.unwrap_or(elem);
                if stride < elem {
                    return Err(format!(
                        "buffer view {v} has byteStride {stride}, smaller than the {elem}-byte elements of accessor {i}"
                    ));
                }
                let off = a.byte_offset.map_or(0, |o| o.0);
                let end = match count {
                    0 => Some(off),
                    n => (n - 1)
                        .checked_mul(stride as u64)
                        .and_then(|x| x.checked_add(off))
                        .and_then(|x| x.checked_add(elem as u64)),
                };
                if end.is_none_or(|e| e > bytes.len() as u64) {
                    return Err(format!(
                        "{what} accessor {i} reads past the end of buffer view {v} ({count} elements of {elem} bytes, stride {stride}, offset {off}, view length {})",
                        bytes.len()
                    ));
                }
                let (count, off) = (count as usize, off as usize);
                out = Vec::with_capacity(count * dims);
                for e in 0..count {
                    let at = off + e * stride;
                    for c in 0..dims {
                        let x = read_component(bytes, at + c * csize, comp, a.normalized)
                            .ok_or_else(|| format!("{what} accessor {i} reads out of bounds"))?;
                        out.push(x);
                    }
                }
            }
        }
        if let Some(sp) = &a.sparse {
            self.apply_sparse(i, sp, &mut out, dims, comp, a.normalized, what)?;
        }
        Ok((out, comp))
    }

    #[allow(clippy::too_many_arguments)]
    fn apply_sparse(
        &self,
        i: usize,
        sp: &json::accessor::sparse::Sparse,
        out: &mut [f64],
        dims: usize,
        comp: ComponentType,
        normalized: bool,
        what: &str,
    ) -> std::result::Result<(), String> {
        let n = usize::try_from(sp.count.0).unwrap_or(usize::MAX);
        let icomp = match sp.indices.component_type {
            Checked::Valid(c) => c.0,
            Checked::Invalid => {
                return Err(format!("{what} accessor {i}: sparse indices have an invalid component type"))
            }
        };
        let (ib, _) = self.view_bytes(sp.indices.buffer_view.value())?;
        let (vb, _) = self.view_bytes(sp.values.buffer_view.value())?;
        let ioff = usize::try_from(sp.indices.byte_offset.0).unwrap_or(usize::MAX);
        let voff = usize::try_from(sp.values.byte_offset.0).unwrap_or(usize::MAX);
        let isize = component_size(icomp);
        let csize = component_size(comp);
        let bad = || format!("{what} accessor {i}: sparse data reads past its buffer view");
        for k in 0..n.min(out.len()) {
            let at = k.checked_mul(isize).and_then(|x| x.checked_add(ioff));
            let target = at.and_then(|at| read_component(ib, at, icomp, false)).ok_or_else(bad)? as usize;
            for c in 0..dims {
                let at = k.checked_mul(dims * csize).and_then(|x| x.checked_add(voff)?.checked_add(c * csize));
                let x = at.and_then(|at| read_component(vb, at, comp, normalized)).ok_or_else(bad)?;
                let slot = target
                    .checked_mul(dims)
                    .and_then(|t| out.get_mut(t.checked_add(c)?))
                    .ok_or_else(|| format!("{what} accessor {i}: sparse index {target} is out of range"))?;
                *slot = x;
            }
        }
        if n > out.len() / dims.max(1) {
            return Err(format!("{what} accessor {i}: sparse count {n} exceeds the accessor count"));
        }
        Ok(())
    }

    fn read_vec3(&self, i: usize, what: &str) -> std::result::Result<Vec<Vec3>, String> {
        let (v, _) = self.read_accessor(i, &[Type::Vec3], what)?;
        Ok(v.chunks_exact(3).map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)).collect())
    }

    fn read_vec2(&self, i: usize, what: &str) -> std::result::Result<Vec<Vec2>, String> {
        let (v, _) = self.read_accessor(i, &[Type::Vec2], what)?;
        Ok(v.chunks_exact(2).map(|c| Vec2::new(c[0] as f32, c[1] as f32)).collect())
    }

    fn read_indices(&self, i: usize) -> std::result::Result<Vec<u32>, String> {
        let (v, comp) = self.read_accessor(i, &[Type::Scalar], "index")?;
        match comp {
            ComponentType::U8 | ComponentType::U16 | ComponentType::U32 => {
                Ok(v.into_iter().map(|x| x as u32).collect())
            }
            c => {
                Err(format!("index accessor {i} has component type {c:?}; indices must be unsigned byte, short or int"))
            }
        }
    }
}

// ---- scene building -----------------------------------------------------------------------

struct Loader<'a> {
    root: &'a json::Root,
    /// The GLB BIN chunk, and the buffer it belongs to (the first one without a URI).
    bin: Option<&'a [u8]>,
    bin_owner: Option<usize>,
    /// Buffers, loaded on first use.
    buffers: Vec<OnceCell<std::result::Result<BufferData<'a>, AssetError>>>,
    assets: &'a AssetReader,
    /// Bytes to read of each external buffer file, by URI.
    uri_want: HashMap<&'a str, u64>,
    scene: Scene,
    /// Converted primitives: (mesh, primitive) → mesh id, or `None` when skipped.
    meshes: HashMap<(usize, usize), Option<MeshId>>,
    materials: Vec<Option<MaterialId>>,
    images: Vec<Option<Option<Arc<Texture>>>>,
    default_material: Option<MaterialId>,
    skipped: Vec<String>,
}

fn node_label(root: &json::Root, i: usize) -> String {
    match root.nodes.get(i).and_then(|n| n.name.as_deref()) {
        Some(name) => format!("node {i} ('{name}')"),
        None => format!("node {i}"),
    }
}

impl Loader<'_> {
    fn build(&mut self) -> std::result::Result<(), String> {
        let root = self.root;
        let roots: Vec<usize> = match root.scene.map(|s| s.value()) {
            Some(s) => {
                let sc = root.scenes.get(s).ok_or_else(|| format!("the default scene {s} does not exist"))?;
                sc.nodes.iter().map(|n| n.value()).collect()
            }
            None => match root.scenes.first() {
                Some(sc) => sc.nodes.iter().map(|n| n.value()).collect(),
                None => {
                    let mut is_child = vec![false; root.nodes.len()];
                    for n in &root.nodes {
                        for c in n.children.iter().flatten() {
                            if let Some(f) = is_child.get_mut(c.value()) {
                                *f = true;
                            }
                        }
                    }
                    (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
                }
            },
        };
        let mut visited = vec![false; root.nodes.len()];
        // (glTF node, parent scene node, does the parent pass a material down?)
        let mut stack: Vec<(usize, Option<NodeId>, bool, String)> =
            roots.iter().rev().map(|&n| (n, None, false, "the scene".to_string())).collect();
        while let Some((i, parent, inherits, referrer)) = stack.pop() {
            let node = root.nodes.get(i).ok_or_else(|| format!("{referrer} lists node {i}, which does not exist"))?;
            if std::mem::replace(&mut visited[i], true) {
                return Err(format!(
                    "{} is reached twice (from {referrer}): the node graph has a cycle or a node with two parents",
                    node_label(root, i)
                ));
            }
            let label = node_label(root, i);
            let name = node.name.clone().unwrap_or_else(|| format!("node {i}"));
            let local = match node.matrix {
                Some(m) => crate::affine_from_mat4(&Mat4::from_cols_array(&m), &label),
                None => {
                    let t = node.translation.unwrap_or([0.0; 3]);
                    let r = node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
                    let s = node.scale.unwrap_or([1.0; 3]);
                    Transform { translation: Vec3::from(t), rotation: Quat::from_array(r), scale: Vec3::from(s) }
                        .to_affine(&label)
                }
            }
            .map_err(|e| e.to_string())?;

            // The primitives this node draws.
            let mut prims = Vec::new();
            if let Some(m) = node.mesh {
                let m = m.value();
                let mesh =
                    root.meshes.get(m).ok_or_else(|| format!("{label} refers to mesh {m}, which does not exist"))?;
                for p in 0..mesh.primitives.len() {
                    if let Some((mesh_id, mat)) = self.primitive(m, p)? {
                        prims.push((p, mesh_id, mat));
                    }
                }
            }
            let mut desc = NodeDesc::new(name.clone()).matrix(local);
            if let [(_, mesh_id, mat)] = prims[..] {
                desc.mesh = Some(mesh_id);
                desc.material = self.resolve_material(mat, inherits);
            }
            let id = self.scene.add_node(parent, desc).map_err(|e| e.to_string())?;
            let passes = inherits || self.scene.node(id).is_some_and(|n| n.material().is_some());
            if prims.len() > 1 {
                for (p, mesh_id, mat) in prims {
                    let mut d = NodeDesc::new(format!("{name} primitive {p}")).mesh(mesh_id);
                    d.material = self.resolve_material(mat, inherits);
                    self.scene.add_node(Some(id), d).map_err(|e| e.to_string())?;
                }
            }
            if let Some(c) = node.camera {
                self.camera(c.value(), id, &label);
            }
            for c in node.children.iter().flatten().rev() {
                stack.push((c.value(), Some(id), passes, label.clone()));
            }
        }
        Ok(())
    }

    /// The material a primitive's node gets: its own, or — when an ancestor would otherwise
    /// pass one down (glTF has no material inheritance) — the default material.
    fn resolve_material(&mut self, own: Option<MaterialId>, inherits: bool) -> Option<MaterialId> {
        own.or_else(|| {
            inherits.then(|| *self.default_material.get_or_insert_with(|| self.scene.add_material(Material::default())))
        })
    }

    /// Converts (once) primitive `p` of mesh `m`; `None` when it is not drawn as triangles.
    #[allow(clippy::type_complexity)]
    fn primitive(&mut self, m: usize, p: usize) -> std::result::Result<Option<(MeshId, Option<MaterialId>)>, String> {
        let mesh = &self.root.meshes[m];
        let prim = &mesh.primitives[p];
        let label = match &mesh.name {
            Some(n) => format!("mesh {m} ('{n}') primitive {p}"),
            None => format!("mesh {m} primitive {p}"),
        };
        let material = match prim.material {
            Some(mi) => Some(self.material(mi.value()).map_err(|e| format!("{label}: {e}"))?),
            None => None,
        };
        if let Some(&cached) = self.meshes.get(&(m, p)) {
            return Ok(cached.map(|id| (id, material)));
        }
        let converted = self.convert_primitive(m, p).map_err(|e| format!("{label}: {e}"))?;
        let id = match converted {
            Some(mesh) => Some(self.scene.add_mesh(mesh)),
            None => {
                let mode = match prim.mode {
                    Checked::Valid(md) => format!("{md:?}"),
                    Checked::Invalid => "invalid".into(),
                };
                self.skipped.push(format!("{label} ({mode})"));
                None
            }
        };
        self.meshes.insert((m, p), id);
        Ok(id.map(|id| (id, material)))
    }

    fn convert_primitive(&self, m: usize, p: usize) -> std::result::Result<Option<Mesh>, String> {
        let mesh = &self.root.meshes[m];
        let prim = &mesh.primitives[p];
        let mode = match prim.mode {
            Checked::Valid(Mode::Triangles) => Mode::Triangles,
            Checked::Valid(Mode::TriangleStrip) => Mode::TriangleStrip,
            Checked::Valid(Mode::TriangleFan) => Mode::TriangleFan,
            Checked::Valid(_) => return Ok(None),
            Checked::Invalid => return Err("unknown primitive mode".into()),
        };
        let attr = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|a| a.value());
        let pos = attr(Semantic::Positions).ok_or("no POSITION attribute")?;
        let positions = self.read_vec3(pos, "POSITION")?;
        let n = positions.len();
        let normals = match attr(Semantic::Normals) {
            Some(a) => Some(self.read_vec3(a, "NORMAL")?),
            None => None,
        };
        let uvs = match attr(Semantic::TexCoords(0)) {
            Some(a) => Some(self.read_vec2(a, "TEXCOORD_0")?),
            None => None,
        };
        let seq = match prim.indices {
            Some(a) => self.read_indices(a.value())?,
            None => {
                let n = u32::try_from(n).map_err(|_| format!("{n} vertices is too many"))?;
                (0..n).collect()
            }
        };
        let indices = match mode {
            Mode::TriangleStrip => seq
                .windows(3)
                .enumerate()
                .flat_map(|(i, w)| if i % 2 == 0 { [w[0], w[1], w[2]] } else { [w[0], w[2], w[1]] })
                .collect(),
            Mode::TriangleFan => match seq.split_first() {
                Some((&first, rest)) => rest.windows(2).flat_map(|w| [first, w[0], w[1]]).collect(),
                None => Vec::new(),
            },
            _ => seq,
        };
        let name = match (&mesh.name, mesh.primitives.len()) {
            (Some(nm), 1) => nm.clone(),
            (Some(nm), _) => format!("{nm} primitive {p}"),
            (None, 1) => format!("mesh {m}"),
            (None, _) => format!("mesh {m} primitive {p}"),
        };
        Mesh::new(name, positions, normals, uvs, indices).map(Some).map_err(|e| e.to_string())
    }

    fn material(&mut self, i: usize) -> std::result::Result<MaterialId, String> {
        if let Some(Some(id)) = self.materials.get(i) {
            return Ok(*id);
        }
        let mat = self.root.materials.get(i).ok_or_else(|| format!("material {i} does not exist"))?;
        let label = match &mat.name {
            Some(n) => format!("material {i} ('{n}')"),
            None => format!("material {i}"),
        };
        let pbr = &mat.pbr_metallic_roughness;
        let mut base_color = pbr.base_color_factor.0;
        if !base_color.iter().all(|c| c.is_finite()) {
            self.scene.warnings.push(format!("{label}: baseColorFactor {base_color:?} is not finite; using white"));
            base_color = [1.0; 4];
        }
        let mut texture = None;
        if let Some(info) = &pbr.base_color_texture {
            match self.base_color_texture(info) {
                Ok(t) => texture = t,
                Err(AssetError::Refused(e)) => return Err(format!("{label}: base color texture: {e}")),
                Err(AssetError::Unavailable(e)) => self
                    .scene
                    .warnings
                    .push(format!("{label}: base color texture: {e}; using the base color factor alone")),
            }
        }
        let id = self.scene.add_material(Material {
            name: mat.name.clone().unwrap_or_else(|| format!("material {i}")),
            base_color,
            base_color_texture: texture,
        });
        if let Some(slot) = self.materials.get_mut(i) {
            *slot = Some(id);
        }
        Ok(id)
    }

    fn base_color_texture(
        &mut self,
        info: &json::texture::Info,
    ) -> std::result::Result<Option<Arc<Texture>>, AssetError> {
        let bad = AssetError::Unavailable;
        if info.tex_coord != 0 {
            return Err(bad(format!("it uses TEXCOORD_{}, only TEXCOORD_0 is loaded", info.tex_coord)));
        }
        let t = info.index.value();
        let tex = self.root.textures.get(t).ok_or_else(|| bad(format!("texture {t} does not exist")))?;
        let img = tex.source.value();
        if let Some(Some(cached)) = self.images.get(img) {
            return Ok(cached.clone());
        }
        let image = self
            .root
            .images
            .get(img)
            .ok_or_else(|| bad(format!("texture {t} refers to image {img}, which does not exist")))?;
        let label = match (&image.uri, &image.name) {
            (Some(uri), _) => format!("image {img} ('{}')", short_uri(uri)),
            (None, Some(name)) => format!("image {img} ('{name}')"),
            (None, None) => format!("image {img}"),
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
        let decoded = decode_texture(bytes).map_err(|e| bad(format!("{label}: {e}")))?;
        let decoded = Some(Arc::new(decoded));
        if let Some(slot) = self.images.get_mut(img) {
            *slot = Some(decoded.clone());
        }
        Ok(decoded)
    }

    fn camera(&mut self, c: usize, node: NodeId, node_label: &str) {
        let Some(cam) = self.root.cameras.get(c) else {
            self.scene.warnings.push(format!("{node_label} refers to camera {c}, which does not exist; ignored"));
            return;
        };
        let name = cam.name.clone().unwrap_or_else(|| format!("camera {c}"));
        let projection = match (&cam.type_, &cam.perspective, &cam.orthographic) {
            (Checked::Valid(json::camera::Type::Perspective), Some(p), _) => {
                let far = p.zfar.unwrap_or(DEFAULT_FAR.max(p.znear * 1.0e4));
                let aspect = p.aspect_ratio.unwrap_or(DEFAULT_ASPECT);
                Projection::perspective(p.yfov, aspect, p.znear, far).map_err(|e| e.to_string())
            }
            (Checked::Valid(json::camera::Type::Orthographic), _, Some(o)) => {
                Projection::orthographic(-o.xmag.abs(), o.xmag.abs(), -o.ymag.abs(), o.ymag.abs(), o.znear, o.zfar)
                    .map_err(|e| e.to_string())
            }
            _ => Err("its type and parameters do not match".to_string()),
        };
        match projection {
            Ok(projection) => self.scene.cameras.push(SceneCamera { name, node, projection }),
            Err(e) => self.scene.warnings.push(format!("camera {c} ('{name}') on {node_label}: {e}; ignored")),
        }
    }
}

/// Largest texture side accepted, in texels.
const MAX_TEXTURE_SIDE: u32 = 16384;

/// Decodes a PNG or JPEG image (format sniffed from the bytes) into an RGBA8 [`Texture`].
pub(crate) fn decode_texture(bytes: &[u8]) -> std::result::Result<Texture, String> {
    let mut reader =
        image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format().map_err(|e| e.to_string())?;
    if reader.format().is_none() {
        return Err("unknown image format (PNG and JPEG are supported)".into());
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_known_vectors() {
        assert_eq!(base64_decode("TWFu").unwrap(), b"Man");
        assert_eq!(base64_decode("TWE=").unwrap(), b"Ma");
        assert_eq!(base64_decode("TQ==").unwrap(), b"M");
        assert_eq!(base64_decode("").unwrap(), b"");
        assert!(base64_decode("T*==").is_err());
    }

    #[test]
    fn percent_decoding_keeps_malformed_escapes() {
        assert_eq!(percent_decode("a%20b"), b"a b");
        assert_eq!(percent_decode("a%2"), b"a%2");
        assert_eq!(percent_decode("%zz"), b"%zz");
        assert_eq!(percent_decode("%FF"), [0xFF]);
    }

    #[test]
    fn glb_header_checks() {
        assert!(split_glb(b"glTF").unwrap_err().contains("truncated"));
        let mut b = b"glTF".to_vec();
        b.extend(2u32.to_le_bytes());
        b.extend(1000u32.to_le_bytes());
        b.extend([0u8; 12]);
        assert!(split_glb(&b).unwrap_err().contains("header says 1000"));
    }
}

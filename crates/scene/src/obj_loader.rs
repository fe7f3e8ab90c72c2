//! Wavefront OBJ loader (via `tobj`), with `.mtl` materials.
//!
//! * Faces are triangulated as fans (a quad `a b c d` gives `a b c`, `a c d`), in file order.
//!   Points and lines (`f` with one or two vertices, `l`) are ignored.
//! * The scene has one root node named after the file; each object or group (`o`/`g`, and a
//!   `usemtl` change inside one, which `tobj` splits off) becomes a child node with its own mesh.
//!   A file without `o`/`g` lines and without material changes loads as ONE mesh whose
//!   triangles are in the file's face order — so a file written by
//!   [`export_obj`](crate::export::export_obj) keeps its triangle IDs.
//! * Each mesh holds the vertices its faces use (in first-use order); unreferenced vertices
//!   are fine. Normals and texture coordinates are kept when every vertex of the mesh has one;
//!   `vt` v is flipped (`1 − v`) to this crate's top-row-is-v-0 convention.
//! * `.mtl` (the Wavefront MTL format): `Kd` becomes the base color, `d` (or `1 − Tr`) its
//!   alpha, blended ([`AlphaMode::Blend`]) when below 1, `map_Kd`
//!   the base color texture (PNG/JPEG). A missing or unreadable `.mtl` or a missing texture
//!   is a warning in [`Scene::warnings`]: without its `.mtl` the geometry loads with the
//!   default material, without its texture a material keeps its `Kd` color.
//! * `mtllib` and `map_Kd` files are found relative to the OBJ file's folder and read under
//!   the rules of [`crate::assets`]: inside that folder (or an allowed root), regular files
//!   only, each read once, within a total. A library named twice is read (and merged) once.
//!
//! Errors ([`Error::Load`], naming the file): file not found, not a regular file, malformed
//! lines (the `tobj` error, e.g. "face parse error"), face indices out of range (also 0, or relative ones reaching before the first element), NaN or
//! infinite coordinates, an `mtllib` or `map_Kd` that the rules above refuse.

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Vec2, Vec3};

use crate::assets::{AssetError, AssetReader};
use crate::{AlphaMode, Error, LoadOptions, Material, Mesh, NodeDesc, Result, Scene, Texture};

/// Largest texture file read, in bytes.
const MAX_IMAGE_FILE: u64 = 256 << 20;

/// Loads an OBJ file (and the `.mtl` files it names, relative to its folder), with the default
/// [`LoadOptions`] (files inside its folder only).
///
/// The returned scene's world transforms are not yet propagated (call
/// [`Scene::update_transforms`], or use [`crate::load`], which does).
pub fn load_obj(path: &Path) -> Result<Scene> {
    load_obj_with(path, &LoadOptions::default())
}

/// [`load_obj`] with options: other folders `mtllib`/`map_Kd` files may come from, a read cap.
pub fn load_obj_with(path: &Path, options: &LoadOptions) -> Result<Scene> {
    let assets = AssetReader::new(path, options).map_err(|e| Error::load(path, e))?;
    let file = assets.open_main().map_err(|e| Error::load(path, e))?;
    load_with_reader(std::io::BufReader::with_capacity(1 << 16, file), path, &assets)
}

/// Loads OBJ text from a reader. `path` names the file in messages and the root node, and its
/// folder resolves `mtllib` references (under the default [`LoadOptions`]).
pub fn load_obj_reader(reader: impl BufRead, path: &Path) -> Result<Scene> {
    load_obj_reader_with(reader, path, &LoadOptions::default())
}

/// [`load_obj_reader`] with options.
pub fn load_obj_reader_with(reader: impl BufRead, path: &Path, options: &LoadOptions) -> Result<Scene> {
    let assets = AssetReader::new(path, options).map_err(|e| Error::load(path, e))?;
    load_with_reader(reader, path, &assets)
}

fn load_with_reader(mut reader: impl BufRead, path: &Path, assets: &AssetReader) -> Result<Scene> {
    // `..Default::default()` keeps this compiling if another crate turns on tobj's
    // `merging`/`reordering` features (which add fields).
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let warnings = RefCell::new(Vec::new());
    // The first refused library: the load fails with it once tobj returns.
    let refused: RefCell<Option<String>> = RefCell::new(None);
    let libraries: RefCell<HashSet<PathBuf>> = RefCell::new(HashSet::new());
    let mtl_loader = |mtl: &Path| {
        let text = assets.resolve(mtl).and_then(|file| {
            if !libraries.borrow_mut().insert(file.clone()) {
                return Ok(None); // named before: its materials are already in
            }
            let (bytes, _) = assets.read(&file, u64::MAX, u64::MAX)?;
            match std::str::from_utf8(&bytes) {
                Ok(text) => Ok(Some(text.to_string())),
                Err(e) => Err(AssetError::Unavailable(format!("not UTF-8 text ({e})"))),
            }
        });
        match text {
            Ok(Some(text)) => {
                let mats = parse_mtl(&text, &mtl.display().to_string(), &mut warnings.borrow_mut());
                // tobj's map type is its own hasher's; let `collect` name it.
                let map = mats.iter().enumerate().map(|(i, m)| (m.name.clone(), i)).collect();
                Ok((mats, map))
            }
            Ok(None) => Ok((Vec::new(), Default::default())),
            Err(AssetError::Unavailable(e)) => {
                let e = e.strip_prefix("cannot read: ").unwrap_or(&e);
                warnings
                    .borrow_mut()
                    .push(format!("material library '{}': {e}; using the default material", mtl.display()));
                Err(tobj::LoadError::OpenFileFailed)
            }
            Err(AssetError::Refused(e)) => {
                refused.borrow_mut().get_or_insert_with(|| format!("material library '{}': {e}", mtl.display()));
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    };
    // tobj does unchecked index arithmetic on face indices that are 0, huge, or relative and
    // reaching before the first element (an overflow panic in debug builds, a wrong vertex in
    // release builds): `FaceCheck` refuses those lines before tobj sees them. Any other panic
    // inside tobj still becomes an error here instead of unwinding through the caller (in
    // builds that unwind; the fuzz targets treat even a caught panic as a bug).
    let mut checked = FaceCheck::new(&mut reader);
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut checked, &options, mtl_loader)
    }));
    if let Some(e) = refused.into_inner() {
        return Err(Error::load(path, e));
    }
    if let Some(e) = checked.error {
        return Err(Error::load(path, format!("malformed OBJ: {e}")));
    }
    let (models, materials) = match result {
        Ok(Ok(loaded)) => loaded,
        // tobj's messages name no place: the line it stopped at is the last one served.
        Ok(Err(e)) => {
            return Err(Error::load(path, format!("malformed OBJ: line {}: {e}{}", checked.line_no, checked.quoted())))
        }
        Err(_) => return Err(Error::load(path, "malformed OBJ: the OBJ parser panicked")),
    };
    let materials = materials.unwrap_or_default();
    let mut scene = Scene::new();
    scene.warnings = warnings.into_inner();
    build_scene(&mut scene, models, &materials, assets, path)?;
    for w in &mut scene.warnings {
        *w = format!("{}: {w}", path.display());
    }
    Ok(scene)
}

fn build_scene(
    scene: &mut Scene,
    models: Vec<tobj::Model>,
    materials: &[tobj::Material],
    assets: &AssetReader,
    path: &Path,
) -> Result<()> {
    let root_name = path.file_name().map_or_else(|| "obj".to_string(), |n| n.to_string_lossy().into_owned());
    let root = scene.add_node(None, NodeDesc::new(root_name))?;
    let mut material_ids = HashMap::new();
    let mut textures = HashMap::new();
    for model in models {
        let m = model.mesh;
        if m.indices.is_empty() {
            continue;
        }
        let positions: Vec<Vec3> = m.positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        let n = positions.len();
        let normals = (m.normals.len() == 3 * n)
            .then(|| m.normals.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect());
        let uvs = (m.texcoords.len() == 2 * n)
            .then(|| m.texcoords.chunks_exact(2).map(|c| Vec2::new(c[0], 1.0 - c[1])).collect());
        let mesh = Mesh::new(model.name.clone(), positions, normals, uvs, m.indices)
            .map_err(|e| Error::load(path, format!("object '{}': {e}", model.name)))?;
        let mesh = scene.add_mesh(mesh);
        let mut desc = NodeDesc::new(model.name).mesh(mesh);
        if let Some(mi) = m.material_id {
            if let Some(mat) = materials.get(mi) {
                let id = match material_ids.get(&mi) {
                    Some(&id) => id,
                    None => {
                        let converted = convert_material(mat, assets, &mut textures, &mut scene.warnings)
                            .map_err(|e| Error::load(path, e))?;
                        let id = scene.add_material(converted);
                        material_ids.insert(mi, id);
                        id
                    }
                };
                desc.material = Some(id);
            }
        }
        scene.add_node(Some(root), desc)?;
    }
    Ok(())
}

/// A reader between the OBJ text and tobj that checks the vertex indices of every `f` and `l`
/// line (the Wavefront OBJ format: 1-based, or negative for "relative to the end of the list
/// so far") and stops the read at the first bad one, keeping the reason in `error`.
struct FaceCheck<R> {
    inner: R,
    /// The current line, served to tobj.
    line: Vec<u8>,
    at: usize,
    line_no: usize,
    /// `v`, `vt` and `vn` lines so far.
    counts: [usize; 3],
    error: Option<String>,
}

impl<R: BufRead> FaceCheck<R> {
    fn new(inner: R) -> Self {
        FaceCheck { inner, line: Vec::new(), at: 0, line_no: 0, counts: [0; 3], error: None }
    }

    /// The current line, quoted for a message (cut at 80 characters), or nothing when empty.
    fn quoted(&self) -> String {
        let text = String::from_utf8_lossy(&self.line);
        let text = text.trim();
        match text.char_indices().nth(80) {
            _ if text.is_empty() => String::new(),
            Some((cut, _)) => format!(" ('{}…')", &text[..cut]),
            None => format!(" ('{text}')"),
        }
    }

    /// Checks one line, split into words as tobj splits it; `counts` are the `v`, `vt` and
    /// `vn` lines before it.
    fn check(line: &str, counts: &mut [usize; 3]) -> std::result::Result<(), String> {
        Self::check_words(line.split_whitespace().map(str::as_bytes), counts)
    }

    /// [`FaceCheck::check`] of an ASCII line, on its bytes: the same words (the ASCII
    /// characters `split_whitespace` splits at are tab, line feed, vertical tab, form feed,
    /// carriage return and space), without decoding characters.
    fn check_ascii(line: &[u8], counts: &mut [usize; 3]) -> std::result::Result<(), String> {
        Self::check_words(line.split(|b| matches!(b, b'\t'..=b'\r' | b' ')).filter(|w| !w.is_empty()), counts)
    }

    /// The verdict on a line split into `words` (UTF-8 text each; see [`FaceCheck::check`]).
    /// An index of one to nine digits, not all zeros, is a positive number below `u32::MAX`
    /// and passes without being parsed: nearly every index of a big file.
    fn check_words<'a>(
        mut words: impl Iterator<Item = &'a [u8]>,
        counts: &mut [usize; 3],
    ) -> std::result::Result<(), String> {
        match words.next() {
            Some(b"v") => counts[0] += 1,
            Some(b"vt") => counts[1] += 1,
            Some(b"vn") => counts[2] += 1,
            Some(b"f") | Some(b"l") => {
                for word in words {
                    // '/' is ASCII, so the parts of UTF-8 text are UTF-8 text.
                    for (k, part) in word.split(|&b| b == b'/').enumerate().take(3).filter(|(_, p)| !p.is_empty()) {
                        let plain =
                            part.len() <= 9 && part.iter().all(u8::is_ascii_digit) && part.iter().any(|&b| b != b'0');
                        if plain {
                            continue;
                        }
                        if let (Ok(part), Ok(word)) = (std::str::from_utf8(part), std::str::from_utf8(word)) {
                            Self::check_index(k, part, word, counts[k])?;
                        }
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// Checks `part`, the `k`th index (vertex, texture coordinate, normal) of `word` on an
    /// `f` or `l` line, against `count` such elements so far.
    fn check_index(k: usize, part: &str, word: &str, count: usize) -> std::result::Result<(), String> {
        const KIND: [&str; 3] = ["vertex", "texture coordinate", "normal"];
        // Not a number: tobj reports its own parse error.
        let Ok(x) = part.parse::<i64>() else { return Ok(()) };
        if x == 0 {
            return Err(format!("{} index 0 in '{word}' is out of bounds (OBJ indices start at 1)", KIND[k]));
        }
        if x < 0 && x.unsigned_abs() > count as u64 {
            return Err(format!(
                "relative {} index {x} in '{word}' is out of bounds: it reaches before the first one ({count} so far)",
                KIND[k]
            ));
        }
        if x > u32::MAX as i64 {
            return Err(format!("{} index {x} in '{word}' is out of bounds", KIND[k]));
        }
        Ok(())
    }
}

impl<R: BufRead> std::io::Read for FaceCheck<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = std::io::Read::read(&mut self.fill_buf()?, buf)?;
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for FaceCheck<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        if self.at == self.line.len() && self.error.is_none() {
            self.line.clear();
            self.at = 0;
            self.inner.read_until(b'\n', &mut self.line)?;
            self.line_no += 1;
            // A line that is not UTF-8 goes through unchecked: tobj refuses it.
            let checked = if self.line.is_ascii() {
                Self::check_ascii(&self.line, &mut self.counts)
            } else {
                std::str::from_utf8(&self.line).map_or(Ok(()), |text| Self::check(text, &mut self.counts))
            };
            if let Err(e) = checked {
                self.error = Some(format!("line {}: {e}", self.line_no));
            }
        }
        if let Some(e) = &self.error {
            return Err(std::io::Error::new(std::io::ErrorKind::InvalidData, e.clone()));
        }
        Ok(&self.line[self.at..])
    }

    fn consume(&mut self, n: usize) {
        self.at = (self.at + n).min(self.line.len());
    }
}

/// Converts a tobj material; `textures` caches decoded textures (and failures) by file, so
/// many materials naming one texture decode it once. A texture the asset rules refuse is an
/// error; one that cannot be read or decoded, or past the cap on decoded data
/// ([`crate::LoadOptions::max_decoded_bytes`]), a warning.
fn convert_material(
    m: &tobj::Material,
    assets: &AssetReader,
    textures: &mut HashMap<PathBuf, std::result::Result<Arc<Texture>, AssetError>>,
    warnings: &mut Vec<String>,
) -> std::result::Result<Material, String> {
    let mut out = Material { name: m.name.clone(), ..Material::default() };
    if let Some(kd) = m.diffuse {
        out.base_color = [kd[0], kd[1], kd[2], 1.0];
    }
    // Dissolve (`d`, or `1 − Tr`) below 1 makes the material translucent; `d 1` and no `d`
    // leave it opaque. Values are clamped to [0, 1].
    if let Some(d) = m.dissolve {
        out.base_color[3] = d.clamp(0.0, 1.0);
        if d < 1.0 {
            out.alpha_mode = AlphaMode::Blend;
        }
    }
    if let Some(tex) = &m.diffuse_texture {
        let decoded = assets.resolve(Path::new(tex)).and_then(|file| {
            let t = textures.entry(file).or_insert_with_key(|file| {
                let (bytes, _) = assets.read(file, u64::MAX, MAX_IMAGE_FILE)?;
                Ok(Arc::new(crate::gltf_loader::decode_for_load(&bytes, assets)?))
            });
            t.clone()
        });
        match decoded {
            Ok(t) => out.base_color_texture = Some(t),
            Err(AssetError::Refused(e)) => return Err(format!("material '{}': texture '{tex}': {e}", m.name)),
            Err(AssetError::Unavailable(e)) => {
                let e = e.strip_prefix("cannot read: ").unwrap_or(&e);
                warnings.push(format!("material '{}': texture '{tex}': {e}; using the diffuse color alone", m.name))
            }
        }
    }
    Ok(out)
}

/// A forgiving `.mtl` reader: `newmtl`, `Kd`, `d`/`Tr`, `map_Kd`. A malformed value is a
/// warning, never an error (tobj's own reader panics on a short `Kd` line).
fn parse_mtl(text: &str, file: &str, warnings: &mut Vec<String>) -> Vec<tobj::Material> {
    let mut mats: Vec<tobj::Material> = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let line = line.trim();
        let (key, rest) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
        let rest = rest.trim();
        if key == "newmtl" {
            mats.push(tobj::Material { name: rest.to_string(), ..Default::default() });
            continue;
        }
        let Some(cur) = mats.last_mut() else {
            continue;
        };
        let floats: Vec<f32> = rest.split_whitespace().map_while(|w| w.parse().ok()).collect();
        let mut bad =
            || warnings.push(format!("material library '{file}' line {}: cannot read '{line}'; ignored", ln + 1));
        match key {
            "Kd" => match floats[..] {
                [r, g, b, ..] if [r, g, b].iter().all(|c| c.is_finite()) => cur.diffuse = Some([r, g, b]),
                [v] if v.is_finite() => cur.diffuse = Some([v, v, v]),
                _ => bad(),
            },
            "d" | "Tr" => match floats[..] {
                [v, ..] if v.is_finite() => {
                    cur.dissolve = Some(if key == "d" { v } else { 1.0 - v });
                }
                _ => bad(),
            },
            "map_Kd" => match rest.rsplit(char::is_whitespace).next() {
                Some(name) if !name.is_empty() => cur.diffuse_texture = Some(name.to_string()),
                _ => bad(),
            },
            _ => {}
        }
    }
    mats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mtl_reader_is_forgiving() {
        let mut w = Vec::new();
        let mats = parse_mtl(
            "newmtl a\nKd 0.1 0.2 0.3\nd 0.5\nnewmtl b\nKd 0.5\nKd x\nmap_Kd -s 1 1 1 tex.png\n",
            "t.mtl",
            &mut w,
        );
        assert_eq!(mats.len(), 2);
        assert_eq!(mats[1].name, "b");
        assert_eq!(mats[0].diffuse, Some([0.1, 0.2, 0.3]));
        assert_eq!(mats[0].dissolve, Some(0.5));
        assert_eq!(mats[1].diffuse, Some([0.5, 0.5, 0.5]));
        assert_eq!(mats[1].diffuse_texture.as_deref(), Some("tex.png"));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("line 6"), "{w:?}");
    }

    fn face_error(obj: &str) -> Option<String> {
        let mut r = FaceCheck::new(obj.as_bytes());
        let mut sink = Vec::new();
        let _ = std::io::Read::read_to_end(&mut r, &mut sink);
        if r.error.is_none() {
            assert_eq!(sink, obj.as_bytes(), "the text passes through unchanged");
        }
        r.error
    }

    #[test]
    fn face_indices_that_tobj_cannot_take_are_refused() {
        let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n";
        for ok in ["f 1 2 3", "f -3 -2 -1", "f 1/1/1 2/-1/-1 3//1", "l 1 2", "f 1 2 x", "f 1 2 3 9"] {
            assert_eq!(face_error(&format!("{tri}{ok}\n")), None, "{ok}");
        }
        for (bad, why) in [
            ("f 1//-11 2 3", "line 6: relative normal index -11"),
            ("f 1/-3 2 3", "relative texture coordinate index -3"),
            ("f -4 2 3", "relative vertex index -4"),
            ("f 1/0 2 3", "texture coordinate index 0"),
            ("l 1 0", "vertex index 0"),
            ("f 1//9000000000000000000 2 3", "normal index 9000000000000000000 in '1//9000000000000000000' is out"),
            // Ten digits past u32::MAX, and zeros written long: parsed, not passed as plain.
            ("f 1 2 4294967296", "vertex index 4294967296 in '4294967296' is out of bounds"),
            ("f 1 2/000000000 3", "texture coordinate index 0 in '2/000000000'"),
            // Not ASCII: split at Unicode whitespace, as tobj splits (an ideographic space).
            ("f 1\u{3000}0 2 3", "vertex index 0 in '0'"),
        ] {
            let e = face_error(&format!("{tri}{bad}\n")).unwrap_or_default();
            assert!(e.contains(why), "{bad}: {e}");
        }
    }

    /// ASCII lines split as bytes give the verdicts and counts of the text's split, on lines
    /// made of the tokens that matter (keywords, indices of every kind and length, slashes,
    /// every ASCII whitespace character `split_whitespace` splits at, and some it does not).
    #[test]
    fn ascii_lines_are_checked_as_the_text_check_does() {
        let heads = ["v", "vt", "vn", "f", "l", "fo", "#", "", "vp"];
        let parts = [
            "1",
            "7",
            "12",
            "0",
            "00",
            "000000001",
            "000000000",
            "999999999",
            "1000000000",
            "4294967295",
            "4294967296",
            "-1",
            "-2",
            "-3",
            "-9",
            "+4",
            "-0",
            "x",
            "1e3",
            "9223372036854775808",
            "",
        ];
        let spaces = [" ", "\t", "\x0b", "\x0c", "\r", "  ", " \r", "\x1f", "\x00"];
        let mut rng = crate::rng::Rng::new(5);
        let mut pick = |n: usize| rng.below(n as u32) as usize;
        for _ in 0..20_000 {
            let mut line = String::new();
            if pick(4) == 0 {
                line += spaces[pick(spaces.len())];
            }
            line += heads[pick(heads.len())];
            for _ in 0..pick(5) {
                line += spaces[pick(spaces.len())];
                for s in 0..1 + pick(3) {
                    if s > 0 {
                        line.push('/');
                    }
                    line += parts[pick(parts.len())];
                }
            }
            if pick(2) == 0 {
                line.push('\n');
            }
            let start = [pick(4), pick(4), pick(4)];
            let (mut a, mut b) = (start, start);
            let text = FaceCheck::<&[u8]>::check(&line, &mut a);
            let bytes = FaceCheck::<&[u8]>::check_ascii(line.as_bytes(), &mut b);
            assert_eq!((&text, a), (&bytes, b), "{line:?} from counts {start:?}");
        }
    }
}

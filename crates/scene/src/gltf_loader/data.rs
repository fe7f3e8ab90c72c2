//! The bytes behind a glTF document: the GLB container (header, JSON and BIN chunks), buffer
//! and image URIs (relative files through the asset reader, `data:` URIs in base64), buffer
//! views and accessors (component types, normalization, sparse substitution) — glTF 2.0
//! specification, sections "GLB File Format Specification", "URIs", "Buffers and Buffer
//! Views" and "Accessors".

use super::*;

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    let s = b.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes(s.try_into().ok()?))
}

/// Splits a GLB file into its JSON chunk and optional BIN chunk.
pub(super) fn split_glb(b: &[u8]) -> std::result::Result<(&[u8], Option<&[u8]>), String> {
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
pub(super) const MAX_IMAGE_FILE: u64 = 256 << 20;

/// A buffer's bytes: the GLB BIN chunk, a decoded data URI, or (a prefix of) a file.
pub(super) enum BufferData<'a> {
    Borrowed(&'a [u8]),
    Owned(Vec<u8>),
    Shared(Arc<[u8]>, usize),
}

impl BufferData<'_> {
    pub(super) fn bytes(&self) -> &[u8] {
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
pub(super) fn read_uri<'a>(
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
pub(super) fn short_uri(uri: &str) -> String {
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

/// At most this many accessor elements without buffer data (all zeros) are made per load, so
/// a few bytes of JSON cannot allocate gigabytes (one accessor, or many).
pub(super) const MAX_UNBACKED_ELEMENTS: u64 = 1 << 24;

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
    pub(super) fn view_bytes(&self, v: usize) -> std::result::Result<(&[u8], Option<usize>), AssetError> {
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
    pub(super) fn read_accessor(
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
        // Charged per read, once the accessor is known to be readable (an accessor named by
        // many primitives is decoded for each), at the 4 bytes a component keeps: each
        // primitive keeps its own copy (the doubles decoded here are dropped at once).
        let decoded = count.saturating_mul(dims as u64).saturating_mul(4);
        let charge = || self.charge(decoded, format_args!("decoding {what} accessor {i} ({count} elements)"));
        let mut out;
        match a.buffer_view {
            None => {
                let total = self.unbacked.get().saturating_add(count);
                if total > MAX_UNBACKED_ELEMENTS {
                    return Err(format!(
                        "{what} accessor {i} has no buffer view but {count} elements; a load fills at most {MAX_UNBACKED_ELEMENTS} elements with zeros in all"
                    ));
                }
                charge()?;
                self.unbacked.set(total);
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
                charge()?;
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

    pub(super) fn read_vec3(&self, i: usize, what: &str) -> std::result::Result<Vec<Vec3>, String> {
        let (v, _) = self.read_accessor(i, &[Type::Vec3], what)?;
        Ok(v.chunks_exact(3).map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)).collect())
    }

    pub(super) fn read_vec2(&self, i: usize, what: &str) -> std::result::Result<Vec<Vec2>, String> {
        let (v, _) = self.read_accessor(i, &[Type::Vec2], what)?;
        Ok(v.chunks_exact(2).map(|c| Vec2::new(c[0] as f32, c[1] as f32)).collect())
    }

    pub(super) fn read_indices(&self, i: usize) -> std::result::Result<Vec<u32>, String> {
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

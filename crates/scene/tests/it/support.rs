//! Fixtures shared by the modules of this test binary: the assets folder, error-message
//! checks, a minimal OBJ, a one-triangle glTF written from JSON.

use std::path::{Path, PathBuf};

use glam::Vec3;
use sightline_scene::{Result, Scene};

/// The three vertices of one triangle, as OBJ `v` lines.
pub const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

/// The path of a file in the repository's `assets` folder.
pub fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets").join(name)
}

/// The error's text; panics when the load succeeded.
pub fn err_text(r: Result<Scene>) -> String {
    match r {
        Ok(s) => {
            panic!("expected an error, got a scene with {} nodes, {} triangles", s.node_count(), s.stats().triangles)
        }
        Err(e) => e.to_string(),
    }
}

/// Asserts that `msg` contains every one of `parts`.
pub fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "message {msg:?} does not mention {p:?}");
    }
}

/// A fresh, empty folder for one test, removed with its contents when the test is done.
pub fn tmp_dir(test: &str) -> TestDir {
    let d = tempfile::Builder::new().prefix(&format!("sightline-{test}-")).tempdir();
    TestDir(d.unwrap_or_else(|e| panic!("cannot make a scratch folder for test {test}: {e}")))
}

/// A test's scratch folder (see [`tmp_dir`]); derefs to its path.
pub struct TestDir(tempfile::TempDir);

impl std::ops::Deref for TestDir {
    type Target = Path;

    fn deref(&self) -> &Path {
        self.0.path()
    }
}

/// Every drawn triangle's world-space corners, in flattened (triangle ID) order.
pub fn world_triangles(scene: &Scene) -> Vec<[Vec3; 3]> {
    let mut out = Vec::new();
    for inst in scene.instances() {
        let mesh = scene.mesh(inst.mesh).unwrap();
        for t in 0..mesh.triangle_count() {
            out.push(mesh.triangle_positions(t).map(|p| inst.world_from_local.transform_point3(p)));
        }
    }
    out
}

/// Standard base64 (with padding), for data URIs.
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A one-triangle glTF with an embedded buffer: `positions` then u16 `indices`; `edit`
/// changes the JSON before it is written.
pub fn tiny_gltf(dir: &Path, name: &str, indices: &[u16], edit: impl FnOnce(&mut serde_json::Value)) -> PathBuf {
    let mut buf = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in p {
            buf.extend(c.to_le_bytes());
        }
    }
    for i in indices {
        buf.extend(i.to_le_bytes());
    }
    let mut doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "holder", "mesh": 0}],
        "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
            {"bufferView": 1, "componentType": 5123, "count": indices.len(), "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 2 * indices.len()}
        ],
        "buffers": [{"byteLength": buf.len(), "uri": format!("data:application/octet-stream;base64,{}", base64(&buf))}]
    });
    edit(&mut doc);
    let path = dir.join(name);
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    path
}

/// A PNG of `side` × `side` transparent black texels (a few kilobytes that decode to
/// `4 side²` bytes).
pub fn blank_png(side: u32) -> Vec<u8> {
    let mut png = Vec::new();
    image::RgbaImage::new(side, side).write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).unwrap();
    png
}

/// A PNG whose header says `side` × `side` texels over an empty image-data chunk: its size
/// can be read, it cannot be decoded.
pub fn png_header_only(side: u32) -> Vec<u8> {
    let mut ihdr = Vec::new();
    ihdr.extend(side.to_be_bytes());
    ihdr.extend(side.to_be_bytes());
    ihdr.extend([8, 6, 0, 0, 0]); // 8-bit RGBA, no interlace
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    for (kind, data) in [(b"IHDR", &ihdr[..]), (b"IDAT", &[][..]), (b"IEND", &[][..])] {
        let body = [&kind[..], data].concat();
        png.extend((data.len() as u32).to_be_bytes());
        png.extend(&body);
        png.extend(crc32(&body).to_be_bytes());
    }
    png
}

/// CRC-32 (ISO-HDLC, as PNG chunks use), bit by bit.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

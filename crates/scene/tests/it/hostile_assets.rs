//! Scene files that reach for files they should not: URIs and `mtllib`/`map_Kd` names that
//! climb out of the asset's folder, are absolute, or pass through a link that leads out; FIFOs
//! and devices named as buffers or material libraries; many buffers naming one file; reads over
//! the total cap. Each must end in an error naming the reference and the reason (or load, when
//! an option allows it), never hang and never read without bound.

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use sightline_scene::gltf_loader::{load_gltf, load_gltf_with};
use sightline_scene::obj_loader::{load_obj, load_obj_with};
use sightline_scene::{load, load_with, LoadOptions};

use crate::support::{assert_mentions, err_text, TestDir, TRI};

/// A fresh folder for one test, with the asset folder `asset/` inside it; files "outside" go
/// in the test folder itself.
fn tmp_dir(test: &str) -> TestDir {
    let d = crate::support::tmp_dir(test);
    std::fs::create_dir_all(d.join("asset")).unwrap();
    d
}

/// Runs `f` on another thread and fails the test if it takes longer than a generous bound (so
/// a load that blocks on a FIFO fails instead of hanging the test run).
fn within_time<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(60)).unwrap_or_else(|_| panic!("{what} did not finish within 60 s"))
}

/// Makes a FIFO, or returns `None` (the test is then skipped) where `mkfifo` is missing.
fn mkfifo(path: &Path) -> Option<()> {
    match std::process::Command::new("mkfifo").arg(path).status() {
        Ok(s) if s.success() => Some(()),
        _ => {
            eprintln!("skipped: cannot make a FIFO with mkfifo");
            None
        }
    }
}

/// One triangle's positions, as the 36 bytes of a glTF buffer.
fn triangle_bytes() -> Vec<u8> {
    [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0].iter().flat_map(|f| f.to_le_bytes()).collect()
}

/// A glTF with one node per entry of `drawn`, each drawing one triangle whose positions come
/// from buffer `drawn[i]`; `buffers` lists each buffer's (URI, byteLength).
fn gltf_doc(buffers: &[(&str, usize)], drawn: &[usize]) -> serde_json::Value {
    serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": (0..drawn.len()).collect::<Vec<_>>()}],
        "nodes": (0..drawn.len()).map(|i| serde_json::json!({"mesh": i})).collect::<Vec<_>>(),
        "meshes": (0..drawn.len())
            .map(|i| serde_json::json!({"primitives": [{"attributes": {"POSITION": i}}]}))
            .collect::<Vec<_>>(),
        "accessors": (0..drawn.len())
            .map(|i| serde_json::json!({"bufferView": i, "componentType": 5126, "count": 3, "type": "VEC3"}))
            .collect::<Vec<_>>(),
        "bufferViews": drawn.iter().map(|&b| serde_json::json!({"buffer": b, "byteLength": 36})).collect::<Vec<_>>(),
        "buffers": buffers
            .iter()
            .map(|(uri, len)| serde_json::json!({"uri": uri, "byteLength": len}))
            .collect::<Vec<_>>(),
    })
}

/// Writes a one-triangle glTF whose only buffer is `uri`, as `asset/name`.
fn write_gltf(dir: &Path, name: &str, uri: &str) -> PathBuf {
    write_doc(dir, name, &gltf_doc(&[(uri, 36)], &[0]))
}

fn write_doc(dir: &Path, name: &str, doc: &serde_json::Value) -> PathBuf {
    let path = dir.join("asset").join(name);
    std::fs::write(&path, serde_json::to_string_pretty(doc).unwrap()).unwrap();
    path
}

/// Writes an OBJ naming material library `mtl`, as `asset/name`.
fn write_obj(dir: &Path, name: &str, mtl: &str) -> PathBuf {
    let path = dir.join("asset").join(name);
    std::fs::write(&path, format!("mtllib {mtl}\n{TRI}usemtl red\nf 1 2 3\n")).unwrap();
    path
}

// ---- the asset's folder -------------------------------------------------------------------

#[test]
fn gltf_buffer_climbing_out_of_the_folder_is_refused() {
    let dir = tmp_dir("climb");
    std::fs::write(dir.join("outside.bin"), triangle_bytes()).unwrap();
    std::fs::create_dir_all(dir.join("asset/sub")).unwrap();
    for uri in ["../outside.bin", "%2E%2E/outside.bin", "sub/../../outside.bin"] {
        let path = write_gltf(&dir, "climb.gltf", uri);
        let e = err_text(load_gltf(&path));
        assert_mentions(&e, &["climb.gltf", &format!("buffer 0 ('{uri}')"), "outside the asset folder", "'..'"]);
    }
    // A POSITION buffer that climbs to a system file.
    if !Path::new("/etc/passwd").is_file() {
        return;
    }
    let deep = format!("{}etc/passwd", "../".repeat(dir.components().count() + 2));
    let path = write_gltf(&dir, "passwd.gltf", &deep);
    let e = err_text(load(&path));
    assert_mentions(&e, &["passwd.gltf", &deep, "outside the asset folder"]);
}

#[test]
fn gltf_absolute_buffer_uri_is_refused() {
    let dir = tmp_dir("absolute");
    let outside = dir.join("outside.bin");
    std::fs::write(&outside, triangle_bytes()).unwrap();
    let abs = outside.to_str().unwrap().to_string();
    for uri in [abs.clone(), format!("file://{abs}")] {
        let path = write_gltf(&dir, "abs.gltf", &uri);
        let e = err_text(load(&path));
        assert_mentions(&e, &["abs.gltf", &uri, "outside the asset folder", "absolute path"]);
    }
}

#[cfg(unix)]
#[test]
fn a_link_inside_the_folder_that_leads_out_is_refused() {
    let dir = tmp_dir("link");
    std::fs::write(dir.join("outside.bin"), triangle_bytes()).unwrap();
    std::os::unix::fs::symlink("../outside.bin", dir.join("asset/link.bin")).unwrap();
    let path = write_gltf(&dir, "link.gltf", "link.bin");
    let e = err_text(load(&path));
    assert_mentions(&e, &["link.gltf", "'link.bin'", "outside the asset folder", "symbolic link"]);
    // A link that stays inside is fine.
    std::fs::write(dir.join("asset/inside.bin"), triangle_bytes()).unwrap();
    std::os::unix::fs::symlink("inside.bin", dir.join("asset/alias.bin")).unwrap();
    let path = write_gltf(&dir, "alias.gltf", "alias.bin");
    assert_eq!(load(&path).unwrap().stats().triangles, 1);
}

#[test]
fn an_allowed_root_accepts_files_outside_the_folder() {
    let dir = tmp_dir("allowed");
    let outside = dir.join("outside.bin");
    std::fs::write(&outside, triangle_bytes()).unwrap();
    let mut uris = vec!["../outside.bin".to_string(), outside.to_str().unwrap().to_string()];
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("../outside.bin", dir.join("asset/link.bin")).unwrap();
        uris.push("link.bin".into());
    }
    let opts = LoadOptions::default().allow_root(&*dir);
    for uri in &uris {
        let path = write_gltf(&dir, "allowed.gltf", uri);
        assert!(load(&path).is_err(), "{uri} loads without the option");
        assert_eq!(load_with(&path, &opts).unwrap().stats().triangles, 1, "{uri}");
        assert_eq!(load_gltf_with(&path, &opts).unwrap().stats().triangles, 1, "{uri}");
    }
    // A root that does not exist is an error naming it, not silently ignored.
    let path = write_gltf(&dir, "allowed.gltf", "../outside.bin");
    let missing = dir.join("no-such-folder");
    let e = err_text(load_with(&path, &LoadOptions::default().allow_root(&missing)));
    assert_mentions(&e, &["allowed asset root", "no-such-folder", "file not found"]);
}

#[test]
fn gltf_image_outside_the_folder_is_an_error_not_a_warning() {
    let dir = tmp_dir("image");
    std::fs::write(dir.join("asset/tri.bin"), triangle_bytes()).unwrap();
    std::fs::write(dir.join("secret.png"), b"not read").unwrap();
    let mut doc = gltf_doc(&[("tri.bin", 36)], &[0]);
    doc["meshes"][0]["primitives"][0]["material"] = 0.into();
    doc["materials"] = serde_json::json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    doc["textures"] = serde_json::json!([{"source": 0}]);
    doc["images"] = serde_json::json!([{"uri": "../secret.png"}]);
    let path = write_doc(&dir, "image.gltf", &doc);
    let e = err_text(load(&path));
    assert_mentions(&e, &["image.gltf", "image 0 ('../secret.png')", "outside the asset folder"]);
    // Allowed, it is read (and, not being a PNG, skipped with a warning as before).
    let scene = load_with(&path, &LoadOptions::default().allow_root(&*dir)).unwrap();
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert_mentions(&scene.warnings[0], &["secret.png", "unknown image format"]);
}

#[test]
fn obj_mtllib_and_map_kd_outside_the_folder_are_refused() {
    let dir = tmp_dir("obj-out");
    std::fs::write(dir.join("outside.mtl"), "newmtl red\nKd 1 0 0\n").unwrap();
    let path = write_obj(&dir, "out.obj", "../outside.mtl");
    let e = err_text(load_obj(&path));
    assert_mentions(&e, &["out.obj", "material library '../outside.mtl'", "outside the asset folder"]);
    let opts = LoadOptions::default().allow_root(&*dir);
    let scene = load_obj_with(&path, &opts).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.materials().next().unwrap().1.base_color, [1.0, 0.0, 0.0, 1.0]);

    // A library inside whose texture climbs out.
    std::fs::write(dir.join("asset/tex.mtl"), "newmtl red\nKd 1 0 0\nmap_Kd ../tex.png\n").unwrap();
    std::fs::write(dir.join("tex.png"), b"not read").unwrap();
    let path = write_obj(&dir, "tex.obj", "tex.mtl");
    let e = err_text(load(&path));
    assert_mentions(&e, &["tex.obj", "material 'red'", "texture '../tex.png'", "outside the asset folder"]);
    let scene = load_with(&path, &opts).unwrap();
    assert_mentions(&scene.warnings[0], &["tex.png", "unknown image format"]);
}

// ---- regular files only -------------------------------------------------------------------

#[cfg(unix)]
#[test]
fn obj_mtllib_dev_zero_is_refused_quickly() {
    if !Path::new("/dev/zero").exists() {
        return;
    }
    let dir = tmp_dir("zero");
    let path = write_obj(&dir, "zero.obj", "/dev/zero");
    let p = path.clone();
    let e = err_text(within_time("mtllib /dev/zero", move || load(&p)));
    assert_mentions(&e, &["zero.obj", "material library '/dev/zero'", "outside the asset folder"]);
    // Even where /dev is allowed, a device is not a regular file.
    let opts = LoadOptions::default().allow_root("/dev");
    let e = err_text(within_time("mtllib /dev/zero, /dev allowed", move || load_with(&path, &opts)));
    assert_mentions(&e, &["zero.obj", "'/dev/zero'", "not a regular file (a character device)"]);
    // And the same for a glTF buffer.
    let path = write_gltf(&dir, "zero.gltf", "/dev/zero");
    let opts = LoadOptions::default().allow_root("/dev");
    let e = err_text(within_time("buffer /dev/zero", move || load_with(&path, &opts)));
    assert_mentions(&e, &["zero.gltf", "buffer 0 ('/dev/zero')", "not a regular file (a character device)"]);
}

#[cfg(unix)]
#[test]
fn fifos_are_refused_without_blocking() {
    let dir = tmp_dir("fifo");
    let fifo = dir.join("asset/pipe");
    if mkfifo(&fifo).is_none() {
        return;
    }
    // As an OBJ's material library.
    let path = write_obj(&dir, "pipe.obj", "pipe");
    let e = err_text(within_time("mtllib FIFO", move || load(&path)));
    assert_mentions(&e, &["pipe.obj", "material library 'pipe'", "not a regular file (a FIFO)"]);
    // As a glTF buffer.
    let path = write_gltf(&dir, "pipe.gltf", "pipe");
    let e = err_text(within_time("buffer FIFO", move || load(&path)));
    assert_mentions(&e, &["pipe.gltf", "buffer 0 ('pipe')", "not a regular file (a FIFO)"]);
    // As a texture.
    std::fs::write(dir.join("asset/m.mtl"), "newmtl red\nmap_Kd pipe\n").unwrap();
    let path = write_obj(&dir, "tex.obj", "m.mtl");
    let e = err_text(within_time("map_Kd FIFO", move || load(&path)));
    assert_mentions(&e, &["tex.obj", "texture 'pipe'", "not a regular file (a FIFO)"]);
    // As the scene file itself.
    for name in ["pipe.obj", "pipe.gltf", "pipe.glb"] {
        let main = dir.join("asset").join(name);
        let _ = std::fs::remove_file(&main);
        mkfifo(&main).unwrap();
        let e = err_text(within_time("scene FIFO", move || load(&main)));
        assert_mentions(&e, &[name, "not a regular file (a FIFO)"]);
    }
}

/// A camera path named by a user goes by the same rules: a FIFO or a device is refused at
/// once, naming the file, instead of blocking the walk or reading without end.
#[cfg(unix)]
#[test]
fn a_camera_path_must_be_a_regular_file() {
    use sightline_scene::path::read_path;
    let dir = tmp_dir("path-fifo");
    let fifo = dir.join("path.json");
    if mkfifo(&fifo).is_none() {
        return;
    }
    let e = within_time("camera path FIFO", move || read_path(&fifo)).unwrap_err().to_string();
    assert_mentions(&e, &["path.json", "not a regular file (a FIFO)"]);
    if Path::new("/dev/zero").exists() {
        let e = within_time("camera path /dev/zero", || read_path(Path::new("/dev/zero"))).unwrap_err().to_string();
        assert_mentions(&e, &["/dev/zero", "not a regular file (a character device)"]);
    }
}

#[test]
fn a_directory_is_not_a_buffer_or_a_scene() {
    let dir = tmp_dir("directory");
    std::fs::create_dir_all(dir.join("asset/sub")).unwrap();
    let path = write_gltf(&dir, "dir.gltf", "sub");
    assert_mentions(&err_text(load(&path)), &["dir.gltf", "buffer 0 ('sub')", "not a regular file (a directory)"]);
    std::fs::create_dir_all(dir.join("asset/folder.obj")).unwrap();
    assert_mentions(&err_text(load(dir.join("asset/folder.obj"))), &["folder.obj", "a directory"]);
}

// ---- bounded reads ------------------------------------------------------------------------

/// 150 buffers naming one 1 MiB file, 3 of them drawn: the file is read once (1 MiB), not
/// once per drawn buffer (3 MiB) or per listed buffer (150 MiB).
#[test]
fn many_buffers_naming_one_file_read_it_once_and_only_if_used() {
    let dir = tmp_dir("many");
    let mut big = triangle_bytes();
    big.resize(1 << 20, 0);
    std::fs::write(dir.join("asset/big.bin"), &big).unwrap();
    let buffers = vec![("big.bin", 1 << 20); 150];
    let path = write_doc(&dir, "many.gltf", &gltf_doc(&buffers, &[0, 1, 2]));
    let main = std::fs::metadata(&path).unwrap().len();
    let cap = main + (1 << 20) + (1 << 19);
    let scene = load_with(&path, &LoadOptions::default().max_total_bytes(cap)).unwrap();
    assert_eq!(scene.stats().triangles, 3);
    assert!(load(&path).is_ok());
    // One byte less than the file and the scene together, and the cap is hit.
    let e = err_text(load_with(&path, &LoadOptions::default().max_total_bytes(main + (1 << 20) - 1)));
    assert_mentions(&e, &["many.gltf", "big.bin", &format!("limit of {} bytes", main + (1 << 20) - 1)]);
}

#[test]
fn unused_buffers_are_never_read() {
    let dir = tmp_dir("unused");
    std::fs::write(dir.join("asset/tri.bin"), triangle_bytes()).unwrap();
    let doc = gltf_doc(&[("tri.bin", 36), ("missing.bin", 1000), ("../outside.bin", 36)], &[0]);
    let path = write_doc(&dir, "unused.gltf", &doc);
    let scene = load(&path).unwrap();
    assert_eq!(scene.stats().triangles, 1);
}

#[test]
fn a_buffer_reads_no_more_than_its_byte_length() {
    let dir = tmp_dir("prefix");
    let mut big = triangle_bytes();
    big.resize(4 << 20, 0);
    std::fs::write(dir.join("asset/big.bin"), &big).unwrap();
    // Buffer 1 names the same file with its whole length but has no view: it does not count.
    let path = write_doc(&dir, "prefix.gltf", &gltf_doc(&[("big.bin", 36), ("big.bin", 4 << 20)], &[0]));
    let main = std::fs::metadata(&path).unwrap().len();
    let scene = load_with(&path, &LoadOptions::default().max_total_bytes(main + 36)).unwrap();
    assert_eq!(scene.stats().triangles, 1);
}

#[test]
fn the_total_read_cap_is_an_error_naming_the_limit() {
    let dir = tmp_dir("cap");
    let mut bin = triangle_bytes();
    bin.resize(4096, 0);
    std::fs::write(dir.join("asset/tri.bin"), &bin).unwrap();
    let path = write_doc(&dir, "cap.gltf", &gltf_doc(&[("tri.bin", 4096)], &[0]));
    let main = std::fs::metadata(&path).unwrap().len();
    let e = err_text(load_with(&path, &LoadOptions::default().max_total_bytes(main + 1000)));
    assert_mentions(&e, &["cap.gltf", "buffer 0 ('tri.bin')", &format!("limit of {} bytes", main + 1000)]);
    // The scene file counts too.
    let e = err_text(load_with(&path, &LoadOptions::default().max_total_bytes(10)));
    assert_mentions(&e, &["cap.gltf", "the scene file", "limit of 10 bytes"]);
    // An OBJ's material library counts.
    std::fs::write(dir.join("asset/m.mtl"), format!("newmtl red\nKd 1 0 0\n{}", "# padding\n".repeat(500))).unwrap();
    let obj = write_obj(&dir, "cap.obj", "m.mtl");
    let main = std::fs::metadata(&obj).unwrap().len();
    let e = err_text(load_with(&obj, &LoadOptions::default().max_total_bytes(main + 100)));
    assert_mentions(&e, &["cap.obj", "material library 'm.mtl'", &format!("limit of {} bytes", main + 100)]);
    assert!(load_with(&obj, &LoadOptions::default().max_total_bytes(main + 5100)).is_ok());
}

#[test]
fn an_mtllib_named_many_times_is_read_once() {
    let dir = tmp_dir("mtl-many");
    std::fs::write(dir.join("asset/m.mtl"), format!("newmtl red\nKd 1 0 0\n{}", "# padding\n".repeat(500))).unwrap();
    let path = dir.join("asset/many.obj");
    std::fs::write(&path, format!("{}{TRI}usemtl red\nf 1 2 3\n", "mtllib m.mtl\nmtllib ./m.mtl\n".repeat(1000)))
        .unwrap();
    let main = std::fs::metadata(&path).unwrap().len();
    let scene = load_with(&path, &LoadOptions::default().max_total_bytes(main + 5100)).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.materials().next().unwrap().1.base_color, [1.0, 0.0, 0.0, 1.0]);
}

/// Small PNG files that decode to 16 MB each: an OBJ's textures are charged their texels
/// against the cap on decoded data, like a glTF's.
#[test]
fn obj_textures_are_charged_for_their_texels() {
    let dir = tmp_dir("obj-texels");
    let png = crate::support::blank_png(2048);
    let mut mtl = String::new();
    for k in 0..10 {
        std::fs::write(dir.join(format!("asset/t{k}.png")), &png).unwrap();
        mtl.push_str(&format!("newmtl m{k}\nmap_Kd t{k}.png\n"));
    }
    std::fs::write(dir.join("asset/many.mtl"), mtl).unwrap();
    let mut obj = String::from("mtllib many.mtl\n");
    for k in 0..10 {
        obj.push_str(&format!("o o{k}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m{k}\nf -3 -2 -1\n"));
    }
    let path = dir.join("asset/many.obj");
    std::fs::write(&path, obj).unwrap();
    // Ten textures: 160 MiB of texels, all the load decodes. They fit in 160 MiB exactly; a
    // byte less and the last is skipped with a warning.
    let textured = |s: &sightline_scene::Scene| s.materials().filter(|(_, m)| m.base_color_texture.is_some()).count();
    let scene = load_with(&path, &LoadOptions::default().max_decoded_bytes(160 << 20)).unwrap();
    assert_eq!((textured(&scene), scene.warnings.len()), (10, 0), "{:?}", scene.warnings);
    let scene = load_with(&path, &LoadOptions::default().max_decoded_bytes((160 << 20) - 1)).unwrap();
    assert_eq!(textured(&scene), 9);
    let texture = ["material 'm9'", "texture 't9.png'", "decoding its 2048 × 2048 texels", "max_decoded_bytes"];
    assert_mentions(&scene.warnings[0], &texture);
}

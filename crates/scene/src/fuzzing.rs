//! The fuzzing harness: one function per fuzz target ([`obj`], [`gltf`], [`camera_path`]),
//! shared by the cargo-fuzz targets in `fuzz/` and by the test that replays their corpus and
//! regression inputs under `cargo test`. Not part of the supported API.
//!
//! A load target gets one input that may hold several files (see [`split_files`]): the first
//! is the scene file, the others are files beside it that it can refer to (`mtllib`,
//! `map_Kd`, buffer and image URIs). They are written into the asset folder of a per-thread
//! [`Sandbox`] and the scene is loaded from disk, the way the command line does. The sandbox
//! also holds traps that a load must not fall into:
//!
//! * files *outside* the asset folder with recognizable contents (a material library, a
//!   buffer of one repeated float, a 3×1 texture), named `../outside.*` or reached through
//!   the symbolic links `link.mtl`, `link.bin`, `link.png` inside the folder; a load that
//!   shows their contents panics ("read outside the asset folder");
//! * a FIFO named `fifo` (an open for reading would block: the fuzzer's timeout reports it),
//!   a link `zero` to `/dev/zero` (an unbounded read: the fuzzer's memory limit reports it),
//!   and a directory `sub`.
//!
//! After a successful load the harness exercises the scene cheaply (propagation, statistics,
//! bounds, flattening, world-space triangles, OBJ export for small scenes, cameras), so
//! panics downstream of the loaders are found too; it checks that the flattened view agrees
//! with the statistics.

use std::cell::RefCell;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{Vec2, Vec3};

use crate::{Result, Scene};

/// The marker that introduces another file in a fuzz input: `\n%%file NAME\n`.
pub const FILE_MARKER: &[u8] = b"\n%%file ";

/// At most this many files besides the scene file are taken from one input.
pub const MAX_EXTRA_FILES: usize = 4;

/// World-space triangles computed per load at most (keeps executions fast).
const MAX_TRIANGLES: usize = 20_000;

/// Name of the material in the library outside the asset folder.
const OUTSIDE_MATERIAL: &str = "outside-marker-material";
/// Every float of the buffer outside the asset folder.
const OUTSIDE_FLOAT: f32 = 4242.4242;
/// The texels of the 3×1 texture outside the asset folder.
const OUTSIDE_TEXELS: [u8; 12] = [1, 2, 3, 255, 4, 5, 6, 255, 7, 8, 9, 255];

/// Files the sandbox creates in the asset folder; an input cannot replace them.
const TRAPS: [&str; 6] = ["link.mtl", "link.bin", "link.png", "zero", "fifo", "sub"];

/// Splits a fuzz input into the scene file and the files beside it.
///
/// The input is the scene file's bytes, optionally followed by sections that each start with
/// [`FILE_MARKER`], a file name and a newline. A name must be 1–64 characters of
/// `[A-Za-z0-9._-]`, must not start with a dot and must not be one of the sandbox's traps;
/// sections with other names are dropped, as are sections past [`MAX_EXTRA_FILES`].
pub fn split_files(data: &[u8]) -> (&[u8], Vec<(&str, &[u8])>) {
    let mut cuts = Vec::new();
    let mut at = 0;
    while let Some(i) = find(&data[at..], FILE_MARKER) {
        cuts.push(at + i);
        at += i + FILE_MARKER.len();
    }
    let main = &data[..cuts.first().copied().unwrap_or(data.len())];
    let mut extra = Vec::new();
    for (k, &start) in cuts.iter().enumerate() {
        let end = cuts.get(k + 1).copied().unwrap_or(data.len());
        let section = &data[start + FILE_MARKER.len()..end];
        let (name, body) = match find(section, b"\n") {
            Some(nl) => (&section[..nl], &section[nl + 1..]),
            None => (section, &section[section.len()..]),
        };
        if let Some(name) = std::str::from_utf8(name).ok().filter(|n| valid_name(n)) {
            if extra.len() < MAX_EXTRA_FILES {
                extra.push((name, body));
            }
        }
    }
    (main, extra)
}

fn valid_name(n: &str) -> bool {
    (1..=64).contains(&n.len())
        && !n.starts_with('.')
        && n.bytes().all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b))
        && !TRAPS.contains(&n)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    // The first byte alone first: a slice comparison per position is a `memcmp` call, which
    // the fuzzer's instrumentation makes slow.
    let first = *needle.first()?;
    hay.windows(needle.len()).position(|w| w[0] == first && w == needle)
}

/// A private folder per thread: `outside.*` files, and the asset folder `asset/` with the
/// traps of the module documentation. Removed when the thread ends (if it ends normally).
pub struct Sandbox {
    root: PathBuf,
    asset: PathBuf,
    /// Files written by the last run, removed before the next.
    written: RefCell<Vec<PathBuf>>,
}

impl Sandbox {
    /// Creates a fresh sandbox under the system's temporary folder. Panics when it cannot:
    /// the harness cannot run without one.
    pub fn new() -> Self {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let root = std::env::temp_dir().join(format!("sightline-fuzz-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let asset = root.join("asset");
        std::fs::create_dir_all(asset.join("sub")).expect("creating the fuzz sandbox");
        let mtl = format!("newmtl {OUTSIDE_MATERIAL}\nKd 0.1 0.2 0.3\nmap_Kd outside.png\n");
        let floats: Vec<u8> = std::iter::repeat_n(OUTSIDE_FLOAT.to_le_bytes(), 1024).flatten().collect();
        let mut png = Vec::new();
        image::RgbaImage::from_raw(3, 1, OUTSIDE_TEXELS.to_vec())
            .expect("3x1 texels")
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("encoding the outside texture");
        for (name, bytes) in [("outside.mtl", mtl.as_bytes()), ("outside.bin", &floats[..]), ("outside.png", &png[..])]
        {
            std::fs::write(root.join(name), bytes).expect("writing the fuzz sandbox");
        }
        #[cfg(unix)]
        {
            for ext in ["mtl", "bin", "png"] {
                let _ = std::os::unix::fs::symlink(format!("../outside.{ext}"), asset.join(format!("link.{ext}")));
            }
            let _ = std::os::unix::fs::symlink("/dev/zero", asset.join("zero"));
            // Best effort: without `mkfifo` the FIFO trap is simply absent.
            let _ = std::process::Command::new("mkfifo")
                .arg(asset.join("fifo"))
                .stderr(std::process::Stdio::null())
                .status();
        }
        Sandbox { root, asset, written: RefCell::new(Vec::new()) }
    }

    /// The asset folder: scene files are written here.
    pub fn asset_dir(&self) -> &Path {
        &self.asset
    }

    /// Writes the scene file as `main_name` and the extra files of `data` beside it (after
    /// removing the previous run's files); returns the scene file's path.
    pub fn write(&self, main_name: &str, main: &[u8], extra: &[(&str, &[u8])]) -> PathBuf {
        let mut written = self.written.borrow_mut();
        for f in written.drain(..) {
            let _ = std::fs::remove_file(f);
        }
        let mut put = |name: &str, bytes: &[u8]| {
            let p = self.asset.join(name);
            // `create_new` never follows a link or overwrites: a name repeated in one input
            // keeps its first file.
            if let Ok(mut f) = std::fs::OpenOptions::new().write(true).create_new(true).open(&p) {
                f.write_all(bytes).expect("writing a fuzz input file");
                written.push(p.clone());
            }
            p
        };
        let path = put(main_name, main);
        for (name, bytes) in extra {
            put(name, bytes);
        }
        path
    }
}

impl Default for Sandbox {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for Sandbox {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.root);
    }
}

thread_local! {
    static SANDBOX: Sandbox = Sandbox::new();
}

/// The `obj` target: the input (split by [`split_files`]) is `model.obj` and the files beside
/// it; loads it from disk and exercises the scene.
pub fn obj(data: &[u8]) -> Result<()> {
    load_target(data, "model.obj")
}

/// The `gltf` target: the input (split by [`split_files`]) is `model.glb` when it starts with
/// the GLB magic `glTF`, else `model.gltf`, and the files beside it (`.bin` buffers, images);
/// loads it from disk and exercises the scene.
pub fn gltf(data: &[u8]) -> Result<()> {
    let (main, _) = split_files(data);
    load_target(data, if main.starts_with(b"glTF") { "model.glb" } else { "model.gltf" })
}

fn load_target(data: &[u8], main_name: &str) -> Result<()> {
    let (main, extra) = split_files(data);
    let loaded = SANDBOX.with(|sb| {
        let path = sb.write(main_name, main, &extra);
        crate::load(&path)
    });
    let mut scene = loaded?;
    assert_stayed_inside(&scene, data);
    exercise(&mut scene);
    Ok(())
}

/// Panics when the scene shows the contents of a file outside the asset folder (unless the
/// input itself carries them).
fn assert_stayed_inside(scene: &Scene, input: &[u8]) {
    for (_, m) in scene.materials() {
        assert!(
            m.name != OUTSIDE_MATERIAL || find(input, OUTSIDE_MATERIAL.as_bytes()).is_some(),
            "read outside the asset folder: material '{}' came from ../outside.mtl",
            m.name
        );
        if let Some(t) = &m.base_color_texture {
            assert!(
                !(t.width == 3 && t.height == 1 && t.rgba[..] == OUTSIDE_TEXELS[..]),
                "read outside the asset folder: material '{}' has the texture ../outside.png",
                m.name
            );
        }
    }
    if find(input, &OUTSIDE_FLOAT.to_le_bytes()).is_none() {
        for (_, mesh) in scene.meshes() {
            assert!(
                !mesh.positions().contains(&Vec3::splat(OUTSIDE_FLOAT)),
                "read outside the asset folder: mesh '{}' has positions from ../outside.bin",
                mesh.name()
            );
        }
    }
}

/// Cheap work on a loaded scene, so that panics past the loader are found too.
fn exercise(scene: &mut Scene) {
    scene.update_transforms();
    let stats = scene.stats();
    let instances = scene.instances();
    assert_eq!(instances.len(), stats.instances, "instances() and stats() disagree on the instance count");
    let drawn: u64 = instances.iter().map(|i| i.triangle_count as u64).sum();
    assert_eq!(drawn, stats.triangles, "instances() and stats() disagree on the triangle count");
    std::hint::black_box(scene.world_aabb());
    let mut budget = MAX_TRIANGLES;
    for inst in &instances {
        let Some(mesh) = scene.mesh(inst.mesh) else {
            continue;
        };
        let n = mesh.triangle_count().min(budget);
        budget -= n;
        for t in 0..n {
            std::hint::black_box(mesh.triangle_positions(t).map(|p| inst.world_from_local.transform_point3(p)));
        }
    }
    if stats.triangles <= MAX_TRIANGLES as u64 {
        let _ = crate::export::write_obj(scene, &mut std::io::sink());
    }
    for cam in &scene.cameras {
        let _ = cam.projection.validate();
        std::hint::black_box(cam.projection.clip_from_view());
        std::hint::black_box(scene.node(cam.node).map(|n| n.world_matrix()));
    }
}

/// The `camera_path` target: the input is camera path JSON as `render --path` and `walk
/// --path` read it; every key is turned into a camera (when valid) for two aspects, with its
/// `clip_from_world` and a ray through a corner.
pub fn camera_path(data: &[u8]) -> Result<()> {
    let keys = crate::path::parse_path(data, Path::new("path.json"))?;
    for key in &keys {
        for aspect in [16.0 / 9.0, 1.0] {
            if let Ok(cam) = key.camera(aspect) {
                std::hint::black_box(cam.clip_from_world());
                std::hint::black_box(cam.ray_through_ndc(Vec2::new(-1.0, 1.0)));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_input_splits_into_files_with_safe_names() {
        let (main, extra) =
            split_files(b"mtllib a.mtl\n%%file a.mtl\nnewmtl x\n%%file ../up\nbad\n%%file fifo\ntrap\n%%file b.png");
        assert_eq!(main, b"mtllib a.mtl");
        assert_eq!(extra, vec![("a.mtl", &b"newmtl x"[..]), ("b.png", &b""[..])]);
        assert_eq!(split_files(b"no files").1.len(), 0);
    }

    #[test]
    fn the_traps_are_set_and_guarded() {
        let sb = Sandbox::new();
        let path = sb.write("model.obj", b"mtllib link.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", &[]);
        // The loader refuses the link; were it followed, the harness check would fire.
        let e = crate::load(&path).unwrap_err().to_string();
        assert!(e.contains("outside the asset folder"), "{e}");
        let mut leaked = Scene::new();
        leaked.add_material(crate::Material { name: OUTSIDE_MATERIAL.into(), ..Default::default() });
        let caught = std::panic::catch_unwind(|| assert_stayed_inside(&leaked, b"mtllib ../outside.mtl"));
        assert!(caught.is_err(), "a material from outside must be caught");
    }
}

//! The interactive viewer (`examples/viewer`) in a real window: started under an X virtual
//! framebuffer (`xvfb-run`), it draws a few frames, reads the window's pixels back and saves
//! them; they must be the pixels `sightline render` writes for the same scene, camera and
//! size, and not a blank picture. Without a display it must fail with one clear line.
//!
//! The window tests need `xvfb-run` (`.ci/run` installs it). Where it is missing they fail,
//! saying so, unless `SIGHTLINE_SKIP_WINDOW_TESTS=1` is set.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const EYE: &str = "60,40,70";
const TARGET: &str = "0,0,0";
const SIZE: &str = "160x90";

fn viewer_binary() -> PathBuf {
    crate::support::example_binary("viewer")
}

fn skip_window_tests() -> bool {
    if std::env::var("SIGHTLINE_SKIP_WINDOW_TESTS").is_ok_and(|v| v == "1") {
        eprintln!("SIGHTLINE_SKIP_WINDOW_TESTS=1: the viewer's window test is skipped");
        return true;
    }
    let found = Command::new("sh").args(["-c", "command -v xvfb-run"]).output().is_ok_and(|o| o.status.success());
    assert!(
        found,
        "xvfb-run is not installed, so the viewer cannot be tested in a window: install it \
         (apt-get install xvfb xauth) or set SIGHTLINE_SKIP_WINDOW_TESTS=1 to skip this test"
    );
    false
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sightline-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a temp folder");
    dir
}

fn rgba(path: &Path) -> image::RgbaImage {
    image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgba8()
}

/// The viewer's screenshot after three frames and `sightline render`'s colour picture, both
/// with `camera` (scene, eye, size); `viewer_extra` and `render_extra` go to one each.
fn window_and_headless(
    dir: &Path,
    camera: &[&str],
    viewer_extra: &[&str],
    render_extra: &[&str],
) -> (image::RgbaImage, image::RgbaImage) {
    let shot = dir.join("shot.png");
    let mut args: Vec<OsString> = camera.iter().chain(viewer_extra).map(OsString::from).collect();
    args.extend(["--no-hud", "--after-frames", "3", "--screenshot"].map(OsString::from));
    args.push(shot.clone().into());
    let out = viewer_under_xvfb(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "the viewer failed under xvfb-run: {err}");
    assert!(err.contains("read back from the window"), "the screenshot is the window's pixels: {err}");
    (rgba(&shot), render(dir, camera, render_extra))
}

/// `sightline render`'s colour picture, at one sample per pixel as the window draws it.
fn render(dir: &Path, camera: &[&str], extra: &[&str]) -> image::RgbaImage {
    let render_dir = dir.join("render");
    let out = Command::new(env!("CARGO_BIN_EXE_sightline"))
        .arg("render")
        .args(camera)
        .args(["--aa", "off"])
        .args(extra)
        .arg("--out")
        .arg(&render_dir)
        .output()
        .expect("the program starts");
    assert!(out.status.success(), "render failed: {}", String::from_utf8_lossy(&out.stderr));
    rgba(&render_dir.join("color.png"))
}

/// The viewer's output when run with `args` on a 24-bit virtual screen (xvfb-run's default
/// depth of 8 bits has no true-colour visual). xvfb-run can fail on its own: lose the race
/// for a display number to a server another test starts at the same moment, or fail to
/// remove its temporary folder after the viewer exited (its exit code then replaces the
/// viewer's). It says so ("xvfb-run: error"), and the run is tried again then, never on the
/// viewer's own answer.
fn viewer_under_xvfb(args: &[OsString]) -> Output {
    let run = || {
        Command::new("xvfb-run")
            .args(["-a", "-s", "-screen 0 640x480x24"])
            .arg(viewer_binary())
            .args(args)
            .output()
            .expect("xvfb-run starts")
    };
    let mut out = run();
    for _ in 0..2 {
        if !String::from_utf8_lossy(&out.stderr).contains("xvfb-run: error") {
            break;
        }
        out = run();
    }
    out
}

/// The viewer's exit code and stderr when started in a window with `args` it should refuse
/// after loading the scene.
fn viewer_refusal(dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let mut args: Vec<OsString> = args.iter().map(OsString::from).collect();
    args.push("--screenshot".into());
    args.push(dir.join("none.png").into());
    let out = viewer_under_xvfb(&args);
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// The pixels where two pictures differ.
fn differing(a: &image::RgbaImage, b: &image::RgbaImage) -> Vec<(u32, u32)> {
    assert_eq!(a.dimensions(), b.dimensions());
    a.enumerate_pixels().filter(|(x, y, p)| b.get_pixel(*x, *y) != *p).map(|(x, y, _)| (x, y)).collect()
}

fn assert_same(window: &image::RgbaImage, headless: &image::RgbaImage) {
    assert_eq!(window.dimensions(), (160, 90), "the window has the size asked for");
    let differ = differing(window, headless);
    if let Some(&(x, y)) = differ.first() {
        panic!(
            "{} of {} pixels differ from the headless render, first at ({x}, {y}): window {:?}, render {:?}",
            differ.len(),
            160 * 90,
            window.get_pixel(x, y),
            headless.get_pixel(x, y)
        );
    }
}

#[test]
fn the_viewer_screenshot_is_the_headless_render_of_the_same_camera() {
    if skip_window_tests() {
        return;
    }
    let dir = temp_dir("viewer");
    let camera = ["--scene", "boxfield", "--eye", EYE, "--target", TARGET, "--size", SIZE];
    let (window, headless) = window_and_headless(&dir, &camera, &[], &[]);
    assert_same(&window, &headless);
    // Not blank: the field of boxes covers a good part of the picture, its faces in
    // several shades (flat shading: one per face direction, besides the sky).
    let sky = *window.get_pixel(0, 0);
    let covered = window.pixels().filter(|p| **p != sky).count();
    let mut shades: Vec<[u8; 4]> = window.pixels().map(|p| p.0).collect();
    shades.sort_unstable();
    shades.dedup();
    assert!(covered > 160 * 90 / 4, "only {covered} pixels differ from the sky");
    assert!(shades.len() >= 4, "only {} colours", shades.len());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--path FILE --frame N` starts from that frame of the path, as `render --path FILE --frame
/// N` draws it, its up direction (tilted here) included; a frame past the path's end is one
/// clear error.
#[test]
fn the_viewer_starts_from_a_path_frame() {
    if skip_window_tests() {
        return;
    }
    let dir = temp_dir("viewer-path");
    let path = dir.join("path.json");
    let key = |eye: &str, up: &str| {
        format!(r#"{{"eye":[{eye}],"target":[0,0,0],"up":[{up}],"fovy_deg":50,"near":0.5,"far":400}}"#)
    };
    std::fs::write(&path, format!("[{},{}]", key("60,40,70", "0,1,0"), key("-50,30,60", "0.3,1,0"))).unwrap();
    let path = path.to_str().unwrap();
    let camera = ["--scene", "boxfield", "--path", path, "--frame", "1", "--size", SIZE];
    let (window, headless) = window_and_headless(&dir, &camera, &[], &[]);
    assert_same(&window, &headless);
    let other = render(&dir, &["--scene", "boxfield", "--path", path, "--frame", "0", "--size", SIZE], &[]);
    assert!(differing(&window, &other).len() > 100, "frame 1 is not frame 0");
    let (code, err) = viewer_refusal(&dir, &["--scene", "boxfield", "--path", path, "--frame", "5", "--size", SIZE]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--frame 5") && err.contains("2 frames") && !err.contains("panicked"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// An animated scene plays in the viewer: paused at a time, it shows the pose `render
/// --time` draws at that time, which is not the pose at the start.
#[test]
fn the_viewer_poses_an_animated_scene() {
    if skip_window_tests() {
        return;
    }
    let dir = temp_dir("viewer-animated");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/animated.gltf");
    let camera = [
        "--scene",
        scene,
        "--eye",
        "2.5,1.5,3",
        "--target",
        "2.5,1.5,0",
        "--near",
        "0.1",
        "--far",
        "50",
        "--size",
        SIZE,
    ];
    let (window, headless) = window_and_headless(&dir, &camera, &["--paused", "--time", "1.5"], &["--time", "1.5"]);
    assert_same(&window, &headless);
    let start = render(&dir, &camera, &["--time", "0"]);
    assert!(differing(&window, &start).len() > 20, "the scene moved between 0 s and 1.5 s");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--camera N` starts from the file's own camera, as `render --camera N` draws it; a
/// camera the file does not have is one clear error.
#[test]
fn the_viewer_starts_from_the_file_s_camera() {
    if skip_window_tests() {
        return;
    }
    let dir = temp_dir("viewer-camera");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/nested.gltf");
    let camera = ["--scene", scene, "--camera", "0", "--size", SIZE];
    let (window, headless) = window_and_headless(&dir, &camera, &[], &[]);
    assert_same(&window, &headless);
    // Not the view the viewer frames by itself.
    let framed = render(&dir, &["--scene", scene, "--size", SIZE], &[]);
    assert!(differing(&window, &framed).len() > 100, "the file's camera is not the three-quarter view");
    let (code, err) = viewer_refusal(&dir, &["--scene", scene, "--camera", "7", "--size", SIZE]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--camera 7") && err.contains("camera") && !err.contains("panicked"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn without_a_display_the_viewer_says_so_in_one_line() {
    let out = Command::new(viewer_binary())
        .args(["--scene", "boxfield", "--size", "64x36"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("the viewer starts");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    assert!(err.contains("display") && !err.contains("panicked"), "{err}");
}

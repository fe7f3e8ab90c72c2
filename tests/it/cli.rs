//! The built `sightline` program driven as a user drives it: numbers no command can honour
//! are usage errors (exit 2, one line naming the flag), caught before any scene is built or
//! memory is reserved for them.

use std::process::Command;

/// Runs the program; returns the exit code and stderr.
fn run(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_sightline")).args(args).output().expect("the program starts");
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn huge_frame_and_thread_counts_are_usage_errors() {
    let dir = std::env::temp_dir().join(format!("sightline-cli-{}", std::process::id()));
    let out = dir.join("path.json");
    let out = out.to_str().expect("a UTF-8 temp path");
    let cases: [&[&str]; 9] = [
        &["path", "--frames", "18446744073709551615", "--out", out],
        &["path", "--frames", "100000000", "--out", out],
        &["path", "--frames", "0", "--out", out],
        &["walk", "--frames", "18446744073709551615"],
        &["walk", "--frames", "3000000000"],
        &["bench", "--frames", "0"],
        &["walk", "--threads", "10000"],
        &["render", "--threads", "0"],
        &["bench", "--threads", "100000"],
    ];
    for args in cases {
        let (code, err) = run(args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        let flag = if args.contains(&"--threads") { "--threads" } else { "--frames" };
        assert!(err.contains(flag), "{args:?}: the error names {flag}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: one line: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(!dir.join("path.json").exists(), "nothing was written");
}

/// Whatever clap refuses is one line naming the flag, with exit code 2, as the program's own
/// usage errors are: an unknown flag, a missing argument, a flag without its partner, a
/// percentage out of range.
#[test]
fn usage_errors_are_one_line_naming_the_flag() {
    let cases: [(&[&str], &str); 5] = [
        (&["walk", "--no-such-flag"], "--no-such-flag"),
        (&["path"], "--out"),
        (&["render", "--eye", "1,2,3"], "--target"),
        (&["render", "--target", "0,0,0"], "--eye"),
        (&["merge", "--min-agreement", "150", "--out", "x", "y"], "--min-agreement"),
    ];
    for (args, flag) in cases {
        let (code, err) = run(args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.starts_with("error: ") && err.contains(flag), "{args:?}: names {flag}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: one line: {err}");
    }
    // With no command at all, the whole help goes to stderr, with exit code 2.
    let (code, err) = run(&[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("Usage:") && err.contains("walk") && err.contains("bench"), "{err}");
    // Help still prints in full, to stdout, with success.
    let out = Command::new(env!("CARGO_BIN_EXE_sightline")).args(["walk", "--help"]).output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&out.stdout).contains("--frames"));
}

/// Output that cannot be written is found before any frame is rendered, and `bench` never
/// passes off an earlier run's summary as its own.
#[test]
fn unwritable_output_fails_first_and_bench_never_reprints_an_old_table() {
    let (code, err) = run(&["walk", "--frames", "2", "--size", "64x36", "--out", "/proc/sightline-no"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("output folder") && err.lines().count() == 1, "{err}");
    assert!(!err.contains("ms"), "the walk rendered nothing: {err}");
    let (code, err) = run(&["render", "--size", "64x36", "--json", "/proc/sightline-no/x.json"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("x.json"), "{err}");

    let dir = std::env::temp_dir().join(format!("sightline-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("bench.json"), r#"{"scene":"old","methods":[{"method":"brute","median_ms":1.0}]}"#)
        .unwrap();
    let missing = dir.join("no-such-path.json");
    let (code, err) =
        run(&["bench", "--path", missing.to_str().unwrap(), "--size", "64x36", "--out", dir.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{err}");
    assert!(!dir.join("bench.md").exists(), "no table from the old summary");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `bench` reports where each rasterizing method's frame time goes: a column of `bench.md`
/// (none for ray casting) and the stacked bars of `stages.png`, as well as `stages_median_ms`
/// in `bench.json`.
#[test]
fn bench_reports_where_the_time_goes() {
    let dir = std::env::temp_dir().join(format!("sightline-bench-stages-{}", std::process::id()));
    let (code, err) = run(&["bench", "-s", "city:30000", "-n", "2", "--size", "64x36", "-o", dir.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let md = std::fs::read_to_string(dir.join("bench.md")).unwrap();
    assert!(md.contains("cull / draw / shading ms"), "{md}");
    let row = |m: &str| md.lines().find(|l| l.starts_with(&format!("| {m} |"))).unwrap_or_else(|| panic!("{m}: {md}"));
    let cells = |m: &str| row(m).split('|').map(str::trim).map(String::from).collect::<Vec<_>>();
    let hzb = cells("hzb")[6].split(" / ").map(|v| v.parse::<f64>().unwrap()).collect::<Vec<_>>();
    assert!(hzb.len() == 3 && hzb[1] > 0.0 && hzb[2] > 0.0, "{md}");
    assert_eq!(cells("raycast")[6], "-", "{md}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("bench.json")).unwrap()).unwrap();
    let hzb_json = summary["methods"].as_array().unwrap().iter().find(|m| m["method"] == "hzb").unwrap();
    assert_eq!(format!("{:.2}", hzb_json["stages_median_ms"]["draw"].as_f64().unwrap()), format!("{:.2}", hzb[1]));
    // The draw parts are bars of the chart's second colour.
    let png = image::open(dir.join("stages.png")).unwrap().to_rgb8();
    let draw_colour = png.pixels().filter(|p| p.0 == [221, 132, 82]).count();
    assert!(draw_colour > 1000, "{draw_colour} pixels of the draw parts' colour");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Options that would be silently ignored are usage errors instead.
#[test]
fn options_that_would_be_ignored_are_usage_errors() {
    let cases: [(&[&str], &str); 11] = [
        (&["render", "--projection", "multiview", "--size", "64x1"], "2x2"),
        (&["render", "--size", "8192x100", "--out", "never-written"], "--aa"),
        (&["walk", "--size", "3000x100", "--aa", "4x4", "--out", "never-written"], "--aa"),
        (&["render", "--fov", "30"], "--eye"),
        (&["render", "--up", "0,0,1"], "--eye"),
        (&["render", "--frame", "3"], "--path"),
        (&["render", "--projection", "isometric", "--near", "2"], "--near"),
        (&["render", "--projection", "orthographic", "--far", "50"], "--far"),
        (&["walk", "--png-every", "5"], "--out"),
        (&["render", "--shadows"], "--method raycast"),
        (&["csg", "--out", "demo.jpg"], ".png"),
    ];
    for (args, hint) in cases {
        let (code, err) = run(args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.contains(hint), "{args:?}: the error says {hint}: {err}");
    }
}

/// A near plane the depth buffer cannot resolve is refused with the ratio and the format,
/// instead of a blank picture and exit 0; ray casting, which keeps no depth buffer, renders.
#[test]
fn a_near_plane_too_close_for_the_depth_format_is_refused() {
    let eye = ["--eye", "0,1.7,0", "--target", "0,1.7,10", "--size", "32x18", "-s", "boxfield"];
    for near in ["1e-7", "1e-6"] {
        let mut args = vec!["render"];
        args.extend(eye);
        args.extend(["--near", near]);
        let (code, err) = run(&args);
        assert_eq!(code, Some(1), "--near {near}: {err}");
        assert!(err.contains("near") && err.contains("F32") && err.lines().count() == 1, "{err}");
        args.extend(["--method", "raycast"]);
        let (code, err) = run(&args);
        assert_eq!(code, Some(0), "ray casting --near {near}: {err}");
    }
    let mut args = vec!["render"];
    args.extend(eye);
    args.extend(["--near", "1e-3", "--depth-format", "16"]);
    let (code, err) = run(&args);
    assert_eq!(code, Some(1), "16-bit depth resolves far less: {err}");
    assert!(err.contains("Unorm16"), "{err}");
}

/// Short options for the common flags; `--json` means "a JSON file, `-` for standard output"
/// on every command; commands with one output take a FILE for `--out` and check it first.
#[test]
fn short_options_json_and_out_mean_the_same_on_every_command() {
    let dir = std::env::temp_dir().join(format!("sightline-cli-short-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let d = dir.to_str().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_sightline"))
        .args(["walk", "-s", "boxfield", "-n", "2", "-j", "1", "-m", "hzb", "--size", "32x18", "-o", d, "--json", "-"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("stdout is the JSON summary alone");
    assert_eq!(summary["methods"][0]["frames"], 2);
    assert!(summary.get("scene_update").is_none(), "a static walk updates no scene");
    assert!(dir.join("frames.csv").exists());

    let info = dir.join("info.json");
    let (code, err) = run(&["info", "-s", "boxfield", "--json", info.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&info).unwrap()).unwrap();
    assert!(v["triangles"].as_u64().unwrap() > 0);
    let stdout =
        Command::new(env!("CARGO_BIN_EXE_sightline")).args(["info", "-s", "boxfield", "--json"]).output().unwrap();
    let v2: serde_json::Value = serde_json::from_slice(&stdout.stdout).unwrap();
    assert_eq!(v["triangles"], v2["triangles"]);

    // A single-file output that cannot be written fails before the scene is built.
    for cmd in [&["export-obj", "-o", "/proc/sightline-no/x.obj"][..], &["path", "-o", d]] {
        let (code, err) = run(cmd);
        assert_eq!(code, Some(1), "{cmd:?}: {err}");
        assert!(err.lines().count() == 1 && !err.contains("panicked"), "{err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every projection of `render` reaches a picture of the whole scene without camera options;
/// parallel projections refuse the perspective camera's options instead of ignoring them.
#[test]
fn every_projection_frames_the_whole_scene() {
    let dir = std::env::temp_dir().join(format!("sightline-cli-proj-{}", std::process::id()));
    let npy = dir.join("ids.npy");
    std::fs::create_dir_all(&dir).unwrap();
    for p in ["perspective", "orthographic", "cavalier", "cabinet", "isometric", "dimetric", "trimetric", "multiview"] {
        let (code, err) = run(&[
            "render",
            "-s",
            concat!(env!("CARGO_MANIFEST_DIR"), "/assets/nested.gltf"),
            "--projection",
            p,
            "--size",
            "64x36",
            "--id-out",
            npy.to_str().unwrap(),
        ]);
        assert_eq!(code, Some(0), "{p}: {err}");
        // uint32 IDs after a 128-byte .npy header: some pixel shows a triangle.
        let bytes = std::fs::read(&npy).unwrap();
        let ids = bytes[128..].chunks(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
        assert!(ids.filter(|&i| i != 0).count() > 20, "{p}: the scene is in the picture");
    }
    let (code, err) = run(&["render", "--projection", "isometric", "--eye", "1,1,1", "--target", "0,0,0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--projection perspective"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The glTF file's own camera: what `--eye` at the camera's node with its field of view shows,
/// by either method; a camera the file does not have is an error that says how many it has.
#[test]
fn render_through_the_files_own_camera() {
    let dir = std::env::temp_dir().join(format!("sightline-cli-camera-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let nested = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/nested.gltf");
    let ids = |extra: &[&str], name: &str| -> Vec<u32> {
        let npy = dir.join(name);
        let mut args = vec!["render", "-s", nested, "--size", "120x80", "--id-out", npy.to_str().unwrap()];
        args.extend_from_slice(extra);
        let (code, err) = run(&args);
        assert_eq!(code, Some(0), "{extra:?}: {err}");
        let bytes = std::fs::read(&npy).unwrap();
        bytes[128..].chunks(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
    };
    // nested.gltf's camera "eye": at (10, 1, 10) looking down −z, yfov 0.8 rad, near 0.1, far 100.
    let by_eye = ids(
        &["--eye", "10,1,10", "--target", "10,1,0", "--fov", "45.83662", "--near", "0.1", "--far", "100"],
        "eye.npy",
    );
    for method in ["raster", "raycast"] {
        let own = ids(&["--camera", "0", "--method", method], &format!("{method}.npy"));
        let seen = own.iter().filter(|&&i| i != 0).count();
        assert!(seen > 100, "{method}: the model is in the picture ({seen} pixels)");
        let same = own.iter().zip(&by_eye).filter(|(a, b)| a == b).count();
        assert!(same as f64 >= 0.99 * own.len() as f64, "{method}: {same} of {} pixels as --eye", own.len());
    }
    let (code, err) = run(&["render", "-s", nested, "--camera", "1", "--size", "32x18"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--camera 1") && err.contains("has 1 camera") && err.lines().count() == 1, "{err}");
    let cube = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/cube.obj");
    let (code, err) = run(&["render", "-s", cube, "--camera", "0", "--size", "32x18"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("no cameras"), "{err}");
    let (code, err) = run(&["render", "-s", nested, "--camera", "0", "--projection", "isometric"]);
    assert_eq!(code, Some(2), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A loader warning reaches the user: in `info --json`'s `warnings`, and as one line on
/// standard error from the commands that draw.
#[test]
fn loader_warnings_reach_the_user() {
    let dir = std::env::temp_dir().join(format!("sightline-cli-warn-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/nested_embedded.gltf")).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    doc["extensionsUsed"] = serde_json::json!(["EXT_made_up"]);
    let file = dir.join("warns.gltf");
    std::fs::write(&file, doc.to_string()).unwrap();
    let f = file.to_str().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_sightline")).args(["info", "-s", f, "--json"]).output().unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let warnings = v["warnings"].as_array().expect("a warnings array");
    assert!(warnings.len() == 1 && warnings[0].as_str().unwrap().contains("EXT_made_up"), "{v}");
    let plain = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/nested.gltf");
    let out = Command::new(env!("CARGO_BIN_EXE_sightline")).args(["info", "-s", plain, "--json"]).output().unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["warnings"], serde_json::json!([]), "a clean file has an empty array");
    for cmd in [&["render", "--size", "32x18"][..], &["walk", "-n", "1", "--size", "32x18"]] {
        let mut args = cmd.to_vec();
        args.extend(["-s", f]);
        let (code, err) = run(&args);
        assert_eq!(code, Some(0), "{err}");
        let lines: Vec<&str> = err.lines().filter(|l| l.contains("EXT_made_up")).collect();
        assert_eq!(lines.len(), 1, "{cmd:?}: one line per warning: {err}");
        assert!(lines[0].starts_with("warning: "), "{err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `render`'s picture is supersampled by default, its IDs and depth are not: `--aa 2x2` and
/// `--aa off` write the same `.npy` buffers and `ids.png`, and different `color.png` (the
/// edges smoothed); the city's triangle count stays 1,000,342 with its windows.
#[test]
fn render_supersamples_the_picture_but_not_the_ids() {
    let dir = std::env::temp_dir().join(format!("sightline-cli-aa-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = |aa: &str| {
        let d = dir.join(aa);
        let (ids, depth) = (d.join("ids.npy"), d.join("depth.npy"));
        std::fs::create_dir_all(&d).unwrap();
        let args = ["render", "-s", "city:30000", "--eye", "26,1.7,60", "--target", "26,6,-60", "--size", "96x64"];
        let (code, err) = run(&[
            &args[..],
            &["--aa", aa, "--out", d.to_str().unwrap(), "--id-out", ids.to_str().unwrap()],
            &["--depth-out", depth.to_str().unwrap()],
        ]
        .concat());
        assert_eq!(code, Some(0), "--aa {aa}: {err}");
        let read = |f: &str| std::fs::read(d.join(f)).unwrap();
        (read("ids.npy"), read("depth.npy"), read("ids.png"), image::open(d.join("color.png")).unwrap().to_rgba8())
    };
    let (a, b) = (out("off"), out("2x2"));
    assert!(a.0 == b.0 && a.1 == b.1 && a.2 == b.2, "IDs and depth do not depend on --aa");
    let differ = a.3.pixels().zip(b.3.pixels()).filter(|(x, y)| x != y).count();
    assert!(differ > 20, "only {differ} pixels of the picture changed");
    let (code, err) = run(&["render", "-s", "city:30000", "--aa", "3x3"]);
    assert_eq!(code, Some(2), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
    let info = Command::new(env!("CARGO_BIN_EXE_sightline")).args(["info", "--json"]).output().unwrap();
    let v: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(v["triangles"], 1_000_342, "the default city's triangle count");
}

/// An animated walk reports what updating the scene cost per frame, apart from the methods'
/// frame times: in its JSON summary, on the line under the table and per frame in the CSV,
/// where every method's record of a frame carries the frame's one update.
#[test]
fn an_animated_walk_reports_its_scene_update() {
    let dir = std::env::temp_dir().join(format!("sightline-cli-update-{}", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_sightline"))
        .args(["walk", "-s", "city+traffic:5", "-n", "3", "-m", "all", "--size", "32x18", "--json", "-", "-o"])
        .arg(&dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("stdout is the JSON summary alone");
    let u = &summary["scene_update"];
    assert_eq!(u["frames"], 3, "once per frame, not per method: {summary}");
    assert!(err.contains("scene update per frame") && err.contains("over 3 frames"), "{err}");
    // The CSV's column, per frame: one value shared by the frame's methods.
    let csv = std::fs::read_to_string(dir.join("frames.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name}: {header:?}"));
    let (frame, update) = (col("frame"), col("scene_update_ms"));
    let mut per_frame: Vec<(u32, f64)> = Vec::new();
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        let (k, ms): (u32, f64) = (f[frame].parse().unwrap(), f[update].parse().unwrap());
        match per_frame.iter().find(|p| p.0 == k) {
            Some(&(_, first)) => assert_eq!(ms, first, "frame {k}: the methods' records disagree"),
            None => per_frame.push((k, ms)),
        }
    }
    assert_eq!(per_frame.len(), 3, "{csv}");
    // The summary is made of those values (the CSV keeps three decimals).
    let mut ms: Vec<f64> = per_frame.iter().map(|p| p.1).collect();
    ms.sort_by(f64::total_cmp);
    let near = |key: &str, want: f64| {
        let got = u[key].as_f64().unwrap();
        assert!((got - want).abs() <= 6e-4, "{key}: {got} against the CSV's {want} ({ms:?})");
    };
    near("median_ms", ms[1]);
    near("max_ms", ms[2]);
    near("mean_ms", ms.iter().sum::<f64>() / 3.0);
    let _ = std::fs::remove_dir_all(&dir);
}

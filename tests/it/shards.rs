//! A long walk split into shards (`walk --frame-range`) and joined again (`merge`) gives the
//! report one run gives: the same frames, the same per-frame counts and verdicts, the same
//! pictures. Timings differ from run to run and are not compared. Shards that overlap or
//! come from different walks are refused; frames no shard rendered are reported.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

use serde_json::Value;

const WALK: [&str; 10] = ["walk", "-s", "city:20000", "-m", "all", "--verify", "-n", "9", "--size", "160x90"];

fn sightline(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_sightline")).args(args).output().expect("the program starts");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn walk(dir: &Path, extra: &[&str]) {
    let mut args = WALK.to_vec();
    args.extend(["--out", dir.to_str().unwrap()]);
    args.extend_from_slice(extra);
    let (code, _, err) = sightline(&args);
    assert_eq!(code, Some(0), "{args:?}: {err}");
}

fn merge(out: &Path, shards: &[&Path]) -> (Option<i32>, String, String) {
    let mut args = vec!["merge", "--out", out.to_str().unwrap()];
    args.extend(shards.iter().map(|s| s.to_str().unwrap()));
    sightline(&args)
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// (frame, method, triangles drawn, verified) of every record, in file order.
fn counts(dir: &Path) -> Vec<(u64, String, u64, Value)> {
    let v = json(&dir.join("frames.json"));
    v.as_array()
        .expect("an array of records")
        .iter()
        .map(|r| {
            let drawn = r["triangles_drawn"].as_u64().unwrap();
            (r["frame"].as_u64().unwrap(), r["method"].as_str().unwrap().to_string(), drawn, r["verified"].clone())
        })
        .collect()
}

fn files(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect()
}

fn gif_frames(path: &Path) -> usize {
    let mut d = gif::DecodeOptions::new().read_info(std::fs::File::open(path).unwrap()).unwrap();
    let mut n = 0;
    while d.read_next_frame().unwrap().is_some() {
        n += 1;
    }
    n
}

#[test]
fn two_shards_merged_are_the_single_run() {
    let root = std::env::temp_dir().join(format!("sightline-shards-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let [single, a, b, merged] = ["single", "a", "b", "merged"].map(|n| root.join(n));
    walk(&single, &[]);
    walk(&a, &["--frame-range", "0..4"]);
    walk(&b, &["--frame-range", "4..9"]);
    // In any order.
    let (code, out, err) = merge(&merged, &[&b, &a]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("walk.gif") && out.contains("frames.csv"), "it says where everything went: {out}");

    let (one, joined) = (counts(&single), counts(&merged));
    assert_eq!(joined.len(), one.len(), "as many records");
    let frames = |c: &[(u64, String, u64, Value)]| c.iter().map(|r| r.0).collect::<BTreeSet<_>>();
    assert_eq!(frames(&joined), (0..9).collect(), "every frame once, numbered as in the path");
    for (s, m) in one.iter().zip(&joined) {
        assert_eq!((s.0, &s.1, &s.3), (m.0, &m.1, &m.3), "same frame, method and verdict, in the same order");
        if s.1 != "raycast" {
            assert_eq!(s.3, Value::Bool(true), "every culled frame equals brute force: {s:?}");
        }
        // The hzb method carries last frame's visible set: a shard starts it afresh, so its
        // counts may differ near a shard's start (the pixels never do: verified above).
        if s.1 != "hzb" {
            assert_eq!(s.2, m.2, "frame {} {}: triangles drawn", s.0, s.1);
        }
    }
    let (sj, mj) = (json(&single.join("walk.json")), json(&merged.join("walk.json")));
    for key in ["scene", "size", "method_set", "path_frames", "frame_range"] {
        assert_eq!(sj[key], mj[key], "{key}");
    }
    for (s, m) in sj["methods"].as_array().unwrap().iter().zip(mj["methods"].as_array().unwrap()) {
        assert_eq!(
            (&s["method"], &s["frames"], &s["verified_frames"]),
            (&m["method"], &m["frames"], &m["verified_frames"])
        );
    }
    assert_eq!(files(&single), files(&merged), "the same files: PNG frames, GIF, chart, counters");
    assert_eq!(gif_frames(&single.join("walk.gif")), gif_frames(&merged.join("walk.gif")));
    let mut compared = 0;
    for f in files(&merged).iter().filter(|f| f.ends_with(".png")) {
        let m = image::open(merged.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        // The PNG frames are the same pictures, pixel for pixel (the chart plots times, and
        // the GIF's burned-in times, which differ from run to run).
        if f.starts_with("frame_") && f != "frame_times.png" {
            let s = image::open(single.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
            assert!(s.to_rgba8() == m.to_rgba8(), "{f}: the merged frame is the single run's");
            compared += 1;
        }
    }
    assert!(compared >= 2, "at least two PNG frames were compared");

    // Overlapping shards, shards of different walks, a shard folder that is no walk's.
    let (code, _, err) = merge(&root.join("x"), &[&a, &a]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("overlap"), "{err}");
    let other = root.join("other");
    walk(&other, &["--frame-range", "4..9", "--backface-culling", "off"]);
    let (code, _, err) = merge(&root.join("y"), &[&a, &other]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("not parts of one walk") && err.contains("--backface-culling"), "{err}");
    let (code, _, err) = merge(&root.join("z"), &[&a, &root]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("walk.json"), "{err}");
    // A report whose numbers no walk writes: a frame size past the renderer's limit, a frame
    // range outside the path, records outside the range.
    for (key, bad, says) in [
        ("size", serde_json::json!([100000, 90]), "frame size 100000x90"),
        ("frame_range", serde_json::json!([5, 3]), "frame range 5..3"),
        ("frame_range", serde_json::json!([0, 10]), "frame range 0..10"),
        // Records past the range given (a lone shard is checked too).
        ("frame_range", serde_json::json!([0, 2]), "frames outside the shard's range"),
    ] {
        let forged = root.join("forged");
        let _ = std::fs::remove_dir_all(&forged);
        std::fs::create_dir_all(&forged).unwrap();
        for f in ["walk.json", "frames.json"] {
            std::fs::copy(a.join(f), forged.join(f)).unwrap();
        }
        let mut report = json(&forged.join("walk.json"));
        report[key] = bad;
        std::fs::write(forged.join("walk.json"), report.to_string()).unwrap();
        let (code, _, err) = merge(&root.join("f"), &[&forged]);
        assert_eq!(code, Some(1), "{key}: {err}");
        assert!(err.contains(says) && err.contains("forged"), "{key}: {err}");
    }
    // A gap is reported, and the rest merged.
    let (code, _, err) = merge(&root.join("gap"), &[&a]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("4..9"), "the missing frames are named: {err}");
    assert_eq!(json(&root.join("gap").join("walk.json"))["missing_frames"], serde_json::json!([[4, 9]]));
    let _ = std::fs::remove_dir_all(&root);
}

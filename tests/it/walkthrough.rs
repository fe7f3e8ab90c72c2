//! The headless walkthrough (`examples/walkthrough`) run for a few small frames on the
//! default city and on the models in `assets/`: every file it names is there and decodes,
//! the GIF holds the frames it says, and the CSV has one consistent row per frame.

use std::path::{Path, PathBuf};
use std::process::Command;

fn walkthrough_binary() -> PathBuf {
    crate::support::example_binary("walkthrough")
}

fn gif_frames(path: &Path) -> (u16, u16, usize) {
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::RGBA);
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut d = opts.read_info(file).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let (w, h) = (d.width(), d.height());
    let mut n = 0;
    while let Some(f) = d.read_next_frame().unwrap_or_else(|e| panic!("{}: {e}", path.display())) {
        assert_eq!((f.width, f.height), (w, h), "full frames");
        n += 1;
    }
    (w, h, n)
}

fn walk(scene: &str, method: &str, dir: &Path) {
    let out = Command::new(walkthrough_binary())
        .args(["--scene", scene, "--method", method, "--frames", "4", "--size", "96x54", "--out"])
        .arg(dir)
        .output()
        .expect("the walkthrough starts");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{scene}: {}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("walk.gif") && stdout.contains("frames.csv"), "the summary says where: {stdout}");

    for f in 0..4 {
        let p = dir.join(format!("frame_{f:04}.png"));
        let img = image::open(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())).to_rgba8();
        assert_eq!(img.dimensions(), (96, 54));
        // The first frame is the start view, which shows the scene; later ones may look at
        // the back of one-sided faces.
        let sky = *img.get_pixel(0, 0);
        assert!(f > 0 || img.pixels().any(|p| *p != sky), "{}: something is drawn", p.display());
    }
    assert!(!dir.join("frame_0004.png").exists(), "four frames, no more");
    assert_eq!(gif_frames(&dir.join("walk.gif")), (96, 54, 4), "{scene}: one GIF frame per frame");

    let csv = std::fs::read_to_string(dir.join("frames.csv")).expect("frames.csv");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("column {name}"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 4, "{csv}");
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r.len(), header.len(), "{csv}");
        assert_eq!(r[col("frame")], k.to_string());
        assert_eq!(r[col("method")], method);
        let ms: f64 = r[col("ms")].parse().expect("ms is a number");
        assert!(ms > 0.0, "{csv}");
        if method != "raycast" {
            let drawn: u64 = r[col("clusters_drawn")].parse().expect("clusters_drawn");
            let all: u64 = r[col("clusters")].parse().expect("clusters");
            let culled: u64 = ["culled_by_frustum", "culled_by_backface", "culled_by_occlusion"]
                .iter()
                .map(|c| r[col(c)].parse::<u64>().expect("a count"))
                .sum();
            assert_eq!(drawn + culled, all, "every cluster drawn or culled: {csv}");
            assert!(r[col("triangles_drawn")].parse::<u64>().expect("triangles_drawn") > 0);
            // The frame's parts, timed inside it (three decimals in the file).
            let [cull, draw, shading] =
                ["ms_cull", "ms_draw", "ms_shading"].map(|c| r[col(c)].parse::<f64>().expect("a time"));
            assert!(draw > 0.0 && cull + draw + shading <= ms + 2e-3, "{csv}");
        } else {
            assert!(r[col("ms_draw")].is_empty(), "rays have no draw stage: {csv}");
        }
    }
}

#[test]
fn the_walkthrough_writes_frames_gif_and_csv_for_the_city_and_the_assets() {
    let root = std::env::temp_dir().join(format!("sightline-walkthrough-{}", std::process::id()));
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    let cases = [
        ("city".to_string(), "hzb"),
        (assets.join("nested.glb").display().to_string(), "frustum"),
        (assets.join("cube.obj").display().to_string(), "raycast"),
        // Animated: the vehicles and cranes move along the walk.
        ("city+traffic:50".to_string(), "hzb"),
    ];
    for (k, (scene, method)) in cases.iter().enumerate() {
        let dir = root.join(k.to_string());
        walk(scene, method, &dir);
    }
    let _ = std::fs::remove_dir_all(&root);
}

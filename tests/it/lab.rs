//! `sightline lab` as a script drives it: the files it promises are written, the Markdown
//! table parses, `lab.json` carries every method's agreement with the z-buffer, the z-buffer
//! and the culler agree with it exactly, a method over its size limit is refused with its
//! limit named, and `--scaling` writes its chart and CSV.

use std::path::{Path, PathBuf};
use std::process::Command;

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sightline-lab-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Runs `sightline lab ARGS --out DIR --json -`; returns the JSON summary from stdout.
fn lab(args: &[&str], dir: &Path) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_sightline"))
        .arg("lab")
        .args(args)
        .args(["--out", dir.to_str().unwrap(), "--json", "-"])
        .output()
        .expect("the program starts");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "lab {args:?}: {err}");
    serde_json::from_slice(&out.stdout).expect("stdout is the JSON summary alone")
}

/// The rows of `lab.md`'s table as cells, header first; every row has the header's width.
fn table(md: &str) -> Vec<Vec<String>> {
    let rows: Vec<Vec<String>> = md
        .lines()
        .filter(|l| l.starts_with('|') && !l.starts_with("|---"))
        .map(|l| l.trim().trim_matches('|').split('|').map(|c| c.trim().to_string()).collect())
        .collect();
    assert!(rows.len() >= 2, "a header and rows: {md}");
    for r in &rows {
        assert_eq!(r.len(), rows[0].len(), "row {r:?} against header {:?}", rows[0]);
    }
    rows
}

/// The checks every view gets; returns the JSON's methods by name.
fn check_view(summary: &serde_json::Value, dir: &Path, size: (u32, u32)) -> Vec<(String, f64)> {
    let triangles = summary["triangles"].as_u64().unwrap();
    assert!(triangles > 0);
    let methods = summary["methods"].as_array().unwrap();
    let agreement: Vec<(String, f64)> = methods
        .iter()
        .map(|m| {
            let a = m["agreement_vs_zbuffer"].as_f64().unwrap_or_else(|| panic!("no agreement in {m}"));
            assert!(m["ms"].as_f64().unwrap() >= 0.0);
            assert_eq!(m["triangles"].as_u64(), Some(triangles));
            (m["method"].as_str().unwrap().to_string(), a)
        })
        .collect();
    let get = |name: &str| agreement.iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("{name} ran")).1;
    assert_eq!(get("zbuffer"), 100.0);
    assert_eq!(get("hzb"), 100.0);
    // Ray casting decides edges its own way: at this small size, where edge pixels are a large
    // share of the image, it agrees on 99% or so (99.5% at 192×108 in the render crate's tests).
    assert!(get("raycast") >= 97.0, "{agreement:?}");

    // The files on disk say the same.
    let on_disk: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("lab.json")).unwrap()).unwrap();
    assert_eq!(&on_disk, summary);
    let rows = table(&std::fs::read_to_string(dir.join("lab.md")).unwrap());
    assert_eq!(rows[0][0], "method");
    assert!(rows[0].iter().any(|c| c.starts_with("agreement_vs_zbuffer")));
    let named: Vec<&str> = rows[1..].iter().map(|r| r[0].as_str()).collect();
    for (m, _) in &agreement {
        assert!(named.contains(&m.as_str()), "{m} in lab.md: {named:?}");
        if m != "zbuffer" {
            let diff = image::open(dir.join(format!("diff_{m}.png"))).unwrap();
            assert_eq!((diff.width(), diff.height()), size);
        }
    }
    let sheet = image::open(dir.join("contact_sheet.png")).unwrap();
    assert!(sheet.width() >= size.0 && sheet.height() >= size.1);
    agreement
}

/// The BSP and painter's methods ran, and agree with the z-buffer on ≥ 99.9% of the pixels
/// when the scene has no coplanar overlaps (`nested.gltf` draws one quad twice, as a strip
/// and as a fan with the other diagonal: where they overlap the z-buffer's winner is decided
/// by rounding); the centroid sort ran (its figure is whatever it gets right).
fn object_order_methods_agree(a: &[(String, f64)], coplanar_overlaps: bool) {
    for m in ["bsp", "painter"] {
        let floor = if coplanar_overlaps { 0.0 } else { 99.9 };
        assert!(a.iter().any(|(n, x)| n == m && *x >= floor), "{m}: {a:?}");
    }
    assert!(a.iter().any(|(n, _)| n == "centroid-sort"), "{a:?}");
}

#[test]
fn lab_on_the_gltf_asset_and_a_small_city() {
    let asset = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/nested.gltf");
    let dir = out_dir("asset");
    let s = lab(&["--scene", asset, "--size", "160x90"], &dir);
    let a = check_view(&s, &dir, (160, 90));
    assert!(a.iter().any(|(m, x)| m == "warnock" && *x >= 99.9), "{a:?}");
    object_order_methods_agree(&a, true);
    let _ = std::fs::remove_dir_all(&dir);

    let dir = out_dir("city");
    let s = lab(&["--scene", "city:10000", "--size", "160x90", "--repeat", "2"], &dir);
    let a = check_view(&s, &dir, (160, 90));
    assert!(a.iter().any(|(m, x)| m == "warnock" && *x >= 99.9), "{a:?}");
    object_order_methods_agree(&a, false);
    assert!(s["refused"].as_array().unwrap().is_empty(), "nothing refused at 10^4 triangles: {s}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn lab_refuses_a_method_over_its_limit_and_says_which_size_each_ran_on() {
    let dir = out_dir("refuse");
    // Over Warnock's 131,072 triangles.
    let s = lab(&["--scene", "city:140000", "--size", "48x27"], &dir);
    let refused = s["refused"].as_array().unwrap();
    let w = refused.iter().find(|r| r["method"] == "warnock").expect("warnock refused");
    assert_eq!(w["limit"].as_u64(), Some(131_072));
    assert!(w["reason"].as_str().unwrap().contains("131072"), "{w}");
    assert!(s["methods"].as_array().unwrap().iter().all(|m| m["method"] != "warnock"));
    check_view(&s, &dir, (48, 27));
    let md = std::fs::read_to_string(dir.join("lab.md")).unwrap();
    let row = table(&md).into_iter().find(|r| r[0] == "warnock").expect("warnock listed");
    assert!(row[1].contains("refused") && row[1].contains("131072"), "{row:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn lab_scaling_writes_a_chart_and_a_csv_over_the_city_family() {
    let dir = out_dir("scaling");
    let out = Command::new(env!("CARGO_BIN_EXE_sightline"))
        .args(["lab", "--scaling", "--size", "48x27", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(dir.join("scaling.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("triangles,method,ms,agreement_vs_zbuffer,status"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let sizes: std::collections::BTreeSet<u64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert_eq!(sizes.len(), 5, "five cities: {sizes:?}");
    assert!(*sizes.first().unwrap() >= 1000 && *sizes.last().unwrap() >= 100_000 && *sizes.last().unwrap() < 131_072);
    for r in &rows {
        assert_eq!(r[4], "ran", "{r:?}");
        assert!(r[2].parse::<f64>().unwrap() >= 0.0);
        if r[1] == "zbuffer" || r[1] == "hzb" {
            assert_eq!(r[3], "100.0000", "{r:?}");
        }
    }
    let chart = image::open(dir.join("scaling.png")).unwrap();
    assert!(chart.width() > 0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// On a scene with blended materials the lab adds the A-buffer and depth peeling: peeling
/// with the A-buffer's depth of layers gives its colours, one layer does not; on an opaque
/// scene neither runs.
#[test]
fn lab_adds_the_transparency_methods_where_there_is_transparency() {
    let asset = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/transparent.gltf");
    let dir = out_dir("transparent");
    let s = lab(&["--scene", asset, "--size", "160x90"], &dir);
    let methods = s["methods"].as_array().unwrap();
    let row = |name: &str| methods.iter().find(|m| m["method"] == name).unwrap_or_else(|| panic!("{name} ran: {s}"));
    assert!(row("abuffer")["max_fragments_per_pixel"].as_u64().unwrap() >= 2, "{s}");
    assert_eq!(row("depth-peeling")["pixels_differing_from_abuffer"], 0, "{s}");
    assert!(row("depth-peeling-1")["pixels_differing_from_abuffer"].as_u64().unwrap() > 0, "{s}");
    let _ = std::fs::remove_dir_all(&dir);

    let dir = out_dir("opaque");
    let s = lab(&["--scene", "city:2000", "--size", "64x36"], &dir);
    assert!(s["methods"].as_array().unwrap().iter().all(|m| m["method"] != "abuffer"), "{s}");
    let _ = std::fs::remove_dir_all(&dir);
}

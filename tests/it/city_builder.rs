//! The library example `examples/city_builder.rs` runs: it writes its picture (which decodes
//! and shows the scene) and prints the scene's statistics, whose counts add up.

use std::process::Command;

#[test]
fn the_city_builder_writes_a_picture_and_prints_statistics() {
    let dir = std::env::temp_dir().join(format!("sightline-city-builder-{}", std::process::id()));
    let out = Command::new(crate::support::example_binary("city_builder"))
        .args(["--out", dir.to_str().unwrap()])
        .output()
        .expect("the example starts");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let picture = dir.join("city.png");
    assert!(stdout.contains(&picture.display().to_string()), "it says where the picture is: {stdout}");
    let img = image::open(&picture).unwrap_or_else(|e| panic!("{}: {e}", picture.display())).to_rgba8();
    assert_eq!(img.dimensions(), (1280, 720));
    let sky = *img.get_pixel(0, 0);
    let drawn = img.pixels().filter(|p| **p != sky).count();
    assert!(drawn > 1280 * 720 / 10, "the scene covers the picture: {drawn} pixels");

    // "nodes N, meshes M, instances I" and "triangles T drawn, U stored (…)".
    let number_after = |word: &str| -> u64 {
        let at = stdout.find(word).unwrap_or_else(|| panic!("'{word}' in {stdout}")) + word.len();
        let digits: String = stdout[at..].trim_start().chars().take_while(char::is_ascii_digit).collect();
        digits.parse().unwrap_or_else(|_| panic!("a number after '{word}': {stdout}"))
    };
    let (nodes, meshes, instances) = (number_after("nodes"), number_after("meshes"), number_after("instances"));
    let triangles = number_after("triangles");
    // 3,000 crates and 1,000 placements of a model with 4 drawn nodes, on top of the city.
    assert!(instances >= 3000 + 4000, "{stdout}");
    assert!(nodes > instances, "groups and the model's camera nodes too: {stdout}");
    assert!((4..1000).contains(&meshes), "meshes are stored once, not per placement: {stdout}");
    assert!(triangles >= 300_000 + 3000 * 12 + 1000 * 6, "{stdout}");
    let _ = std::fs::remove_dir_all(&dir);
}

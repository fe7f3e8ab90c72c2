//! `sightline info`: scene statistics.

use std::path::Path;

use anyhow::Result;

pub fn run(scene: &super::SceneArg, json: Option<&Path>) -> Result<()> {
    super::common::check_outputs(&[], json.as_slice())?;
    let spec = &scene.scene;
    let t = std::time::Instant::now();
    let loaded = super::load_scene(scene)?;
    let load_ms = t.elapsed().as_secs_f64() * 1e3;
    let s = loaded.scene.stats();
    let b = loaded.scene.world_aabb();
    if let Some(dest) = json {
        let mut v = serde_json::to_value(s)?;
        v["load_ms"] = serde_json::json!(load_ms);
        v["cameras"] = serde_json::json!(loaded.scene.cameras.len());
        v["warnings"] = serde_json::json!(loaded.scene.warnings);
        v["bounds"] = serde_json::json!({ "min": b.min.to_array(), "max": b.max.to_array() });
        return super::common::write_json(dest, &v, false);
    }
    println!("scene             {}", super::describe(spec));
    println!("nodes             {:>12}", s.nodes);
    println!("meshes            {:>12}", s.meshes);
    println!("instances         {:>12}", s.instances);
    println!("triangles         {:>12}", s.triangles);
    println!("unique triangles  {:>12}", s.unique_triangles);
    println!("degenerate        {:>12}", s.degenerate_triangles);
    println!("materials         {:>12}", s.materials);
    println!("vertex bytes      {:>12}", s.vertex_bytes);
    println!("index bytes       {:>12}", s.index_bytes);
    println!("cameras           {:>12}", loaded.scene.cameras.len());
    println!("bounds            {} .. {}", b.min, b.max);
    println!("built/loaded in   {load_ms:>9.1} ms");
    Ok(())
}

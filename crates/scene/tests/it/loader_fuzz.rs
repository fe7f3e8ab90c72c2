//! Fuzz-style tests: random bytes, and random mutations of the valid assets (byte flips,
//! truncations, numbers in the glTF JSON replaced by awkward values), must give `Ok` or `Err`,
//! never a panic.

use std::io::Cursor;

use proptest::prelude::*;
use sightline_scene::gltf_loader::load_gltf_bytes;
use sightline_scene::obj_loader::load_obj_reader;

use crate::support::asset;

fn read(name: &str) -> Vec<u8> {
    std::fs::read(asset(name)).unwrap()
}

/// Loads both ways; the scene, if any, must also be usable (propagate, flatten).
fn load_all(bytes: &[u8], stem: &str) {
    for ext in ["glb", "gltf"] {
        if let Ok(mut s) = load_gltf_bytes(bytes, &asset(&format!("{stem}.{ext}"))) {
            s.update_transforms();
            let _ = s.instances();
        }
    }
    if let Ok(mut s) = load_obj_reader(Cursor::new(bytes), &asset(&format!("{stem}.obj"))) {
        s.update_transforms();
        let _ = s.instances();
    }
}

fn mutate(mut bytes: Vec<u8>, flips: &[(usize, u8)], cut: Option<usize>) -> Vec<u8> {
    for &(at, b) in flips {
        if !bytes.is_empty() {
            let i = at % bytes.len();
            bytes[i] = b;
        }
    }
    if let Some(c) = cut {
        bytes.truncate(c % (bytes.len() + 1));
    }
    bytes
}

/// Replaces numeric values in the JSON (found by walking it) with awkward ones.
fn mutate_numbers(doc: &mut serde_json::Value, picks: &[(usize, usize)]) {
    const AWKWARD: [f64; 14] =
        [-1.0, 0.0, 1.0, 2.0, 3.0, 5.0, 7.0, 255.0, 65536.0, 4294967295.0, 1e12, 0.5, -1e39, 1e39];
    /// JSON pointers of every number in the document.
    fn leaves(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
        match v {
            serde_json::Value::Number(_) => out.push(at),
            serde_json::Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    leaves(x, format!("{at}/{i}"), out);
                }
            }
            serde_json::Value::Object(o) => {
                for (k, x) in o {
                    leaves(x, format!("{at}/{k}"), out);
                }
            }
            _ => {}
        }
    }
    let mut ptrs = Vec::new();
    leaves(doc, String::new(), &mut ptrs);
    if ptrs.is_empty() {
        return;
    }
    for &(which, value) in picks {
        let x = AWKWARD[value % AWKWARD.len()];
        let new = if x.fract() == 0.0 && (0.0..=4294967295.0).contains(&x) {
            serde_json::Value::from(x as u64)
        } else {
            serde_json::Number::from_f64(x).map(serde_json::Value::Number).unwrap_or(serde_json::Value::Null)
        };
        if let Some(slot) = doc.pointer_mut(&ptrs[which % ptrs.len()]) {
            *slot = new;
        }
    }
}

/// 200 cases per property (a few seconds); set `LOADER_FUZZ_CASES` to run more.
fn cases() -> u32 {
    std::env::var("LOADER_FUZZ_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(200)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic(mut bytes in proptest::collection::vec(any::<u8>(), 0..600), glb_header in any::<bool>()) {
        if glb_header && bytes.len() >= 12 {
            bytes[..4].copy_from_slice(b"glTF");
            bytes[4..8].copy_from_slice(&2u32.to_le_bytes());
        }
        load_all(&bytes, "random");
    }

    #[test]
    fn mutated_glb_never_panics(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..6),
        cut in proptest::option::of(any::<usize>()),
    ) {
        let bytes = mutate(read("nested.glb"), &flips, cut);
        load_all(&bytes, "mutant");
    }

    #[test]
    fn mutated_gltf_json_never_panics(
        picks in proptest::collection::vec((any::<usize>(), any::<usize>()), 1..4),
        embedded in any::<bool>(),
    ) {
        let text = read(if embedded { "nested_embedded.gltf" } else { "nested.gltf" });
        let mut doc: serde_json::Value = serde_json::from_slice(&text).unwrap();
        mutate_numbers(&mut doc, &picks);
        let bytes = serde_json::to_vec(&doc).unwrap();
        // Named next to the real assets, so the external .bin and .png resolve.
        if let Ok(mut s) = load_gltf_bytes(&bytes, &asset("nested.gltf")) {
            s.update_transforms();
            let _ = s.instances();
        }
    }

    #[test]
    fn mutated_obj_never_panics(
        flips in proptest::collection::vec((any::<usize>(), proptest::sample::select(b" \n/-0123456789.fvtnoge#".to_vec())), 0..6),
        cut in proptest::option::of(any::<usize>()),
    ) {
        let bytes = mutate(read("cube.obj"), &flips, cut);
        if let Ok(mut s) = load_obj_reader(Cursor::new(&bytes), &asset("mutant.obj")) {
            s.update_transforms();
            let _ = s.instances();
        }
    }
}

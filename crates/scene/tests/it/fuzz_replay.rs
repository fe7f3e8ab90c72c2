//! Replays the fuzz inputs under `cargo test`: every file of `fuzz/corpus/<target>/` (the
//! seeds) and `fuzz/regressions/<target>/` (minimized inputs that once crashed or hung a
//! target) goes through the same harness function the fuzz target calls
//! (`sightline_scene::fuzzing`). Each must load or fail with an error, never panic; seeds
//! named `trap_*` aim at a file outside the asset folder, a FIFO, a device or a directory and
//! must fail; the seeds made from `assets/` must load.
//!
//! As under libFuzzer, a panic counts even when the library catches it (the OBJ loader wraps
//! its parser in `catch_unwind`, which a `panic = "abort"` build cannot rely on): a panic hook
//! counts the panics of each thread.

use std::cell::Cell;
use std::path::{Path, PathBuf};
use std::sync::Once;

use sightline_scene::fuzzing;

/// A fuzz target's harness function.
type Harness = fn(&[u8]) -> sightline_scene::Result<()>;

/// The harness function of each fuzz target, by directory name.
fn harness(target: &str) -> Option<Harness> {
    match target {
        "obj" => Some(fuzzing::obj),
        "gltf" => Some(fuzzing::gltf),
        "camera_path" => Some(fuzzing::camera_path),
        _ => None,
    }
}

fn fuzz_dir(kind: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz").join(kind)
}

/// (target, file) for every input under `fuzz/<kind>/`, sorted.
fn inputs(kind: &str) -> Vec<(String, PathBuf)> {
    let mut out = Vec::new();
    let Ok(targets) = std::fs::read_dir(fuzz_dir(kind)) else {
        return out;
    };
    for t in targets.flatten().filter(|e| e.path().is_dir()) {
        let target = t.file_name().to_string_lossy().into_owned();
        for f in std::fs::read_dir(t.path()).unwrap().flatten().filter(|e| e.path().is_file()) {
            out.push((target.clone(), f.path()));
        }
    }
    out.sort();
    out
}

thread_local! {
    /// Panics on this thread since the hook was installed, caught or not.
    static PANICS: Cell<usize> = const { Cell::new(0) };
}

/// Installs (once) a panic hook that counts each thread's panics, then runs the previous hook.
fn count_panics() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            PANICS.with(|p| p.set(p.get() + 1));
            previous(info);
        }));
    });
}

/// Runs each input; returns the failures, one line each.
fn replay(inputs: &[(String, PathBuf)]) -> Vec<String> {
    count_panics();
    let mut failures = Vec::new();
    for (target, file) in inputs {
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        let Some(run) = harness(target) else {
            failures.push(format!("{target}/{name}: no fuzz target named '{target}'"));
            continue;
        };
        let data = std::fs::read(file).unwrap();
        let before = PANICS.with(Cell::get);
        let outcome = std::panic::catch_unwind(|| run(&data));
        let caught = PANICS.with(Cell::get) - before;
        match outcome {
            Err(_) => failures.push(format!("{target}/{name}: panicked")),
            Ok(_) if caught > 0 => {
                failures.push(format!("{target}/{name}: panicked inside the library ({caught} caught)"))
            }
            Ok(Ok(())) if name.starts_with("trap_") => {
                failures.push(format!("{target}/{name}: loaded, but it names a file the loader must refuse"))
            }
            Ok(Err(e)) if e.to_string().trim().is_empty() => failures.push(format!("{target}/{name}: empty error")),
            Ok(_) => {}
        }
    }
    failures
}

#[test]
fn seed_corpus_replays_without_panics() {
    let seeds = inputs("corpus");
    for target in ["obj", "gltf", "camera_path"] {
        assert!(seeds.iter().any(|(t, _)| t == target), "no seeds for the {target} target");
    }
    let failures = replay(&seeds);
    assert!(failures.is_empty(), "{} of {} seeds failed:\n{}", failures.len(), seeds.len(), failures.join("\n"));
}

#[test]
fn regressions_replay_without_panics() {
    let regressions = inputs("regressions");
    let failures = replay(&regressions);
    assert!(
        failures.is_empty(),
        "{} of {} regressions failed:\n{}",
        failures.len(),
        regressions.len(),
        failures.join("\n")
    );
}

#[test]
fn seeds_from_the_assets_load() {
    for (target, name) in [
        ("obj", "cube_alone"),
        ("obj", "cube_with_mtl"),
        ("obj", "cube_textured"),
        ("gltf", "nested_external"),
        ("gltf", "nested_embedded"),
        ("gltf", "nested_glb"),
        ("camera_path", "two_keys"),
    ] {
        let data = std::fs::read(fuzz_dir("corpus").join(target).join(name)).unwrap();
        if let Err(e) = harness(target).unwrap()(&data) {
            panic!("{target}/{name} does not load: {e}");
        }
    }
}

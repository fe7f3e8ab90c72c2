//! Fuzz target `obj`: the harness in `sightline_scene::fuzzing` (shared with the replay
//! test under `cargo test`) must return `Ok` or `Err` for every input, never panic or hang.

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = sightline_scene::fuzzing::obj(data);
});

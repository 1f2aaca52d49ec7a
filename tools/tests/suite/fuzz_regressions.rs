//! Replays every input the fuzzers found (kept under `tests/fuzz-regressions/<target>/`) through
//! the code its fuzz target runs: each once crashed, hung or allocated too much, and each must
//! now be read, or refused, without a panic.

use std::path::Path;

#[path = "../../../fuzz/fuzz_targets/common.rs"]
mod common;
#[path = "../../../fuzz/fuzz_targets/config_input.rs"]
mod config_input;

/// The code a fuzz target runs on one input.
type Target = fn(&[u8]);

/// Each fuzz target by name, with the code it runs on one input.
const TARGETS: [(&str, Target); 7] = [
    ("obj", common::obj),
    ("ply", common::ply),
    ("gltf", common::gltf),
    ("image", common::image),
    ("colmap", common::colmap),
    ("bundler", common::bundler),
    ("config", config_input::config),
];

#[test]
fn every_kept_fuzz_finding_is_handled_without_a_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz-regressions");
    let mut replayed = 0;
    for entry in std::fs::read_dir(&root).unwrap().flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name == "README.md" {
            continue;
        }
        // A file anywhere else would never be replayed: refuse it rather than skip it.
        let Some((_, run)) = TARGETS.iter().find(|(t, _)| *t == name) else {
            panic!(
                "{name}: not a fuzz target's folder (expected one of {:?})",
                TARGETS.map(|t| t.0)
            );
        };
        for input in std::fs::read_dir(entry.path()).unwrap().flatten() {
            let bytes = std::fs::read(input.path()).unwrap();
            eprintln!("replaying {name}/{}", input.file_name().to_string_lossy());
            run(&bytes);
            replayed += 1;
        }
    }
    eprintln!("{replayed} kept fuzz inputs replayed");
}

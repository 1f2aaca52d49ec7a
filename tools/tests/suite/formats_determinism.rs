//! Same bytes whatever `--threads` is, in every model and texture format (glTF, GLB, and the
//! parallel TIFF and JPEG encoders; OBJ with PNG is covered in `cli.rs`), and `--merge-only`:
//! merged UVs on the input's own sheets.

use std::path::Path;
use std::process::Output;

use crate::common::{scanatlas, snapshot as files};

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn every_format_gives_the_same_bytes_for_every_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Sheets of 1024² so that the TIFF and JPEG encoders cut each into several strips.
    let cases = [("gltf", "png"), ("glb", "png"), ("obj", "tiff"), ("obj", "jpg"), ("ply", "png")];
    for (model, texture) in cases {
        let src = format!("s-{model}");
        let synth = ["synth", &src, "--faces", "4000", "--sheet-size", "1024", "--sheets", "2"];
        let out = scanatlas(&[&synth[..], &["--format", model, "-q"]].concat(), d);
        assert!(out.status.success(), "{}", stderr(&out));
        let input = format!("{src}/scan.{model}");
        let mut outputs = Vec::new();
        for n in ["1", "2", "3"] {
            let folder = format!("o-{model}-{texture}-{n}");
            let output = format!("{folder}/out.{model}");
            let args =
                ["--threads", n, "defrag", &input, "-o", &output, "--texture-format", texture];
            let out = scanatlas(&[&args[..], &["-q"]].concat(), d);
            assert!(out.status.success(), "{model}/{texture} --threads {n}: {}", stderr(&out));
            outputs.push(files(&d.join(folder)));
        }
        let names: Vec<&Path> = outputs[0].iter().map(|(n, _)| n.as_path()).collect();
        assert!(names.len() >= 2, "{model}/{texture}: only {names:?}");
        for (k, other) in outputs.iter().enumerate().skip(1) {
            for ((name, a), (other_name, b)) in outputs[0].iter().zip(other) {
                assert_eq!(name, other_name, "{model}/{texture}: different files");
                assert!(
                    a == b,
                    "{model}/{texture}: {} differs between 1 and {} threads",
                    name.display(),
                    k + 1
                );
            }
            assert_eq!(outputs[0].len(), other.len(), "{model}/{texture}: {names:?}");
        }
    }
}

#[test]
fn merge_only_merges_onto_the_input_sheets_and_writes_no_texture() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = scanatlas(&["synth", "s", "--faces", "3000", "--sheet-size", "512", "-q"], d);
    assert!(out.status.success(), "{}", stderr(&out));
    let args = ["defrag", "s/scan.obj", "-o", "m/out.obj", "--merge-only", "--report", "r.json"];
    let out = scanatlas(&[&args[..], &["-q"]].concat(), d);
    assert!(out.status.success(), "{}", stderr(&out));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("r.json")).unwrap()).unwrap();
    let (before, after) = (&report["merge"]["charts_before"], &report["merge"]["charts_after"]);
    assert!(after.as_u64().unwrap() < before.as_u64().unwrap(), "{before} → {after}");
    // No texture is written: the output's material reads the input's sheet.
    let written: Vec<String> =
        files(&d.join("m")).into_iter().map(|(n, _)| n.to_string_lossy().into_owned()).collect();
    assert_eq!(written, ["out.mtl", "out.obj"]);
    let mtl = std::fs::read_to_string(d.join("m/out.mtl")).unwrap();
    assert!(mtl.contains("../s/sheet_0.png"), "{mtl}");
    let stats = |model: &str| -> serde_json::Value {
        let out = scanatlas(&["stats", model, "--json"], d);
        assert!(out.status.success(), "{}", stderr(&out));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let (input, merged) = (stats("s/scan.obj"), stats("m/out.obj"));
    assert_eq!(input["faces"], merged["faces"]);
    assert!(merged["charts_edge"].as_u64() < input["charts_edge"].as_u64(), "{merged}");
}

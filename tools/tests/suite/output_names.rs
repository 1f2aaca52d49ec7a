//! End-to-end tests of the output's names: sheets numbered as UDIM tiles after an input whose
//! sheets are (`texture_1001.png`), by index otherwise, and materials named as the input's.

use std::path::Path;
use std::process::Output;

use crate::common::scanatlas;

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A synthetic scan `s/scan.obj` of two 256² sheets whose files are renamed `tex_1001.png` and
/// `tex_1002.png` when `udim`, and whose materials are renamed `skin` and `cloth`.
fn synth(d: &Path, udim: bool) {
    let out =
        scanatlas(&["synth", "s", "--faces", "3000", "--sheet-size", "256", "--sheets", "2"], d);
    assert!(out.status.success(), "{}", stderr(&out));
    let mut mtl = std::fs::read_to_string(d.join("s/scan.mtl")).unwrap();
    let mut obj = std::fs::read_to_string(d.join("s/scan.obj")).unwrap();
    for (k, name) in ["skin", "cloth"].iter().enumerate() {
        mtl = mtl.replace(&format!("newmtl sheet_{k}"), &format!("newmtl {name}"));
        obj = obj.replace(&format!("usemtl sheet_{k}"), &format!("usemtl {name}"));
        if udim {
            let tile = format!("tex_{}.png", 1001 + k);
            mtl = mtl.replace(&format!("sheet_{k}.png"), &tile);
            std::fs::rename(d.join(format!("s/sheet_{k}.png")), d.join("s").join(&tile)).unwrap();
        }
    }
    std::fs::write(d.join("s/scan.mtl"), mtl).unwrap();
    std::fs::write(d.join("s/scan.obj"), obj).unwrap();
}

/// The `newmtl` names and `map_Kd` files of an MTL, in order.
fn materials(mtl: &Path) -> Vec<(String, String)> {
    let text = std::fs::read_to_string(mtl).unwrap();
    let mut out: Vec<(String, String)> = Vec::new();
    for line in text.lines() {
        if let Some(name) = line.strip_prefix("newmtl ") {
            out.push((name.to_string(), String::new()));
        } else if let Some(map) = line.strip_prefix("map_Kd ") {
            out.last_mut().unwrap().1 = map.to_string();
        }
    }
    out
}

/// Runs defrag into `o/out.obj` with `extra`, and returns the output's materials.
fn defrag(d: &Path, extra: &[&str]) -> Vec<(String, String)> {
    let mut args = vec!["defrag", "s/scan.obj", "-o", "o/out.obj", "-q"];
    args.extend_from_slice(extra);
    let out = scanatlas(&args, d);
    assert!(out.status.success(), "{}", stderr(&out));
    materials(&d.join("o/out.mtl"))
}

/// Output material `k`: the input's material of sheet `k`, then `atlas<k>`.
fn expected_name(k: usize) -> String {
    ["skin", "cloth"].get(k).map_or_else(|| format!("atlas{k}"), |n| n.to_string())
}

#[test]
fn udim_inputs_give_udim_sheets_and_materials_keep_their_names() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, true);
    // Small fixed sheets, so the output needs more sheets than the input has materials.
    let mats = defrag(d, &["--sheet-size", "128"]);
    assert!(mats.len() > 2, "expected more than two output sheets: {mats:?}");
    for (k, (name, map)) in mats.iter().enumerate() {
        assert_eq!(name, &expected_name(k));
        assert_eq!(map, &format!("out_{}.png", 1001 + k));
        assert!(d.join("o").join(map).is_file(), "{map} missing");
    }
    assert!(!d.join("o/out_0.png").exists());
    let stats = scanatlas(&["stats", "o/out.obj"], d);
    assert!(stats.status.success(), "{}", stderr(&stats));
}

#[test]
fn other_inputs_give_indexed_sheets() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, false);
    let mats = defrag(d, &[]);
    assert!(!mats.is_empty());
    for (k, (name, map)) in mats.iter().enumerate() {
        assert_eq!(name, &expected_name(k));
        assert_eq!(map, &format!("out_{k}.png"));
    }
}

#[test]
fn a_gltf_keeps_its_image_subfolder_and_the_output_loads() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out =
        scanatlas(&["synth", "g", "--faces", "2000", "--sheet-size", "256", "--format", "gltf"], d);
    assert!(out.status.success(), "{}", stderr(&out));
    std::fs::create_dir(d.join("g/textures")).unwrap();
    std::fs::rename(d.join("g/sheet_0.png"), d.join("g/textures/sheet_0.png")).unwrap();
    let doc = std::fs::read_to_string(d.join("g/scan.gltf")).unwrap();
    let doc = doc.replace("\"uri\": \"sheet_0.png\"", "\"uri\": \"textures/sheet_0.png\"");
    std::fs::write(d.join("g/scan.gltf"), doc).unwrap();

    for output in ["o/out.gltf", "p/out.obj"] {
        let out = scanatlas(&["defrag", "g/scan.gltf", "-o", output, "-q"], d);
        assert!(out.status.success(), "{output}: {}", stderr(&out));
        let folder = d.join(Path::new(output).parent().unwrap());
        assert!(folder.join("textures/out_0.png").is_file(), "{output}: no textures/out_0.png");
        assert!(!folder.join("out_0.png").exists());
        let stats = scanatlas(&["stats", output], d);
        assert!(stats.status.success(), "{output} does not load: {}", stderr(&stats));
        // No staging folder or journal is left beside the output.
        let hidden = std::fs::read_dir(&folder).unwrap().flatten();
        let hidden: Vec<_> =
            hidden.filter(|e| e.file_name().to_string_lossy().starts_with('.')).collect();
        assert!(hidden.is_empty(), "{output}: {hidden:?}");
    }
    let doc = std::fs::read_to_string(d.join("o/out.gltf")).unwrap();
    assert!(doc.contains("\"textures/out_0.png\""), "{doc}");
    let mtl = std::fs::read_to_string(d.join("p/out.mtl")).unwrap();
    assert!(mtl.contains("map_Kd textures/out_0.png"), "{mtl}");
}

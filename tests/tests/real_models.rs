//! The real-data suite: `stats` against the independent evaluator, format round trips and texture
//! round trips on the real photogrammetry models of `SCANATLAS_REAL_DATA`.

use std::path::{Path, PathBuf};
use std::process::Command;

use scanatlas_core::io::{WriteOptions, read_model, write_model};
use scanatlas_core::metrics::{StatsOptions, atlas_stats};
use scanatlas_core::pipeline;
use scanatlas_tests::{assert_same_faces, real_data};

const MODELS: [&str; 3] = [
    "venus-realitycapture/venus.nodraco.gltf",
    "meshroom-esp32cam/texturedMesh.obj",
    "sketchfab-plane-meal/scene.gltf",
];

fn evaluator_input_stats(model: &Path) -> serde_json::Value {
    let evaluate =
        std::env::var_os("SCANATLAS_EVALUATE").expect("SCANATLAS_EVALUATE must name evaluate.py");
    let python = std::env::var_os("SCANATLAS_PYTHON").unwrap_or_else(|| "python3".into());
    let out = Command::new(python)
        .arg(evaluate)
        .arg(model)
        .arg(model)
        .args(["--no-color", "--no-overlap"])
        .output()
        .expect("python runs");
    assert!(out.status.success(), "evaluate.py failed: {}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("evaluator prints JSON");
    v["input"].clone()
}

#[test]
fn stats_agree_with_the_evaluator_within_a_tenth_of_a_percent() {
    let data = real_data();
    for rel in MODELS {
        let path = data.join(rel);
        let model = pipeline::load_model(&path).unwrap_or_else(|e| panic!("{rel}: {e}"));
        let ours = serde_json::to_value(atlas_stats(
            &model,
            &pipeline::sheet_sizes(&model),
            &StatsOptions { overlaps: false },
        ))
        .unwrap();
        let theirs = evaluator_input_stats(&path);
        for key in [
            "faces",
            "vertices_3d",
            "uv_vertices",
            "charts_edge",
            "charts",
            "uv_boundary_length_texels",
            "uv_area_texels",
            "uv_area_charts_texels",
            "atlas_solidity",
            "total_texels",
            "faces_without_uv",
            "uv_degenerate_faces",
            "uv_flipped_faces",
        ] {
            let (a, b) = (ours[key].as_f64(), theirs[key].as_f64());
            let (a, b) = (a.unwrap_or_else(|| panic!("{rel}: we lack {key}")), b.expect(key));
            let tol = 1e-3 * b.abs().max(1.0);
            assert!((a - b).abs() <= tol, "{rel}: {key}: ours {a} vs evaluator {b}");
        }
    }
}

#[test]
fn real_models_round_trip_through_every_format() {
    let data = real_data();
    let dir = tempfile::tempdir().unwrap();
    for rel in MODELS {
        let input = read_model(&data.join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"));
        for ext in ["obj", "gltf", "glb", "ply"] {
            let out: PathBuf = dir.path().join(format!("rt.{ext}"));
            write_model(&input, &out, &WriteOptions::default())
                .unwrap_or_else(|e| panic!("{rel} → {ext}: {e}"));
            let back = read_model(&out).unwrap_or_else(|e| panic!("{rel} → {ext} → read: {e}"));
            // glTF and PLY (MeshLab's `texcoord` lists) store UVs as f32; OBJ keeps f64 exactly.
            let tol = if ext == "obj" { 0.0 } else { 1e-6 };
            assert_same_faces(&input, &back, ext.starts_with("gl"), tol);
        }
    }
}

#[test]
fn draco_venus_gets_a_clear_error() {
    let path = real_data().join("venus-realitycapture/venus.gltf");
    let err = read_model(&path).expect_err("Draco is not decoded").to_string();
    assert!(err.contains("KHR_draco_mesh_compression"), "{err}");
    assert!(err.contains("venus.gltf"), "{err}");
}

#[test]
fn real_textures_survive_the_tile_store_bit_exactly() {
    use scanatlas_core::texture::decode::decode_to_store;
    use scanatlas_core::texture::encode::{EncodeOptions, write_image};
    let data = real_data();
    let dir = tempfile::tempdir().unwrap();
    let png = scanatlas_core::ImageSource::File(data.join("meshroom-esp32cam/texture_1001.png"));
    let store = decode_to_store(&png, dir.path()).unwrap();
    let tif = dir.path().join("t.tif");
    write_image(&store, &tif, &EncodeOptions::default()).unwrap();
    let back = decode_to_store(&scanatlas_core::ImageSource::File(tif), dir.path()).unwrap();
    assert_eq!(
        (store.width(), store.height(), store.format()),
        (back.width(), back.height(), back.format())
    );
    for ty in 0..store.tiles_y() {
        for tx in 0..store.tiles_x() {
            let r = store.tile_rect(tx, ty);
            let bpp = store.format().bytes_per_pixel();
            let (a, b) = (store.tile(tx, ty), back.tile(tx, ty));
            // Compare only the pixels inside the image; padding of edge tiles is unspecified.
            for y in 0..(r.y1 - r.y0) as usize {
                let row = y * scanatlas_core::texture::store::TILE as usize * bpp;
                let n = (r.x1 - r.x0) as usize * bpp;
                assert_eq!(a[row..row + n], b[row..row + n], "tile {tx},{ty} row {y}");
            }
        }
    }
}

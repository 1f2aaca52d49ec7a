//! The real-data suite: `stats` against the independent evaluator, format round trips, texture
//! round trips and whole merges judged by the independent checker, on the real photogrammetry
//! models of `SCANATLAS_REAL_DATA`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use scanatlas_core::io::gltf::with_node_transforms;
use scanatlas_core::io::{WriteOptions, read_model, write_model};
use scanatlas_core::metrics::{StatsOptions, atlas_stats};
use scanatlas_core::pipeline;
use scanatlas_tests::{assert_same_faces, check, real_data};

// Beside the other tests of this binary, in a folder of its own so that Cargo does not take it
// for a test target.
#[path = "real_models/defaults.rs"]
mod defaults;

const MODELS: [&str; 3] = [
    "venus-realitycapture/venus.nodraco.gltf",
    "meshroom-esp32cam/texturedMesh.obj",
    "sketchfab-plane-meal/scene.gltf",
];

/// The least colour PSNR (dB) of a run with a solver other than the default: the lowest of the
/// reference's figures (venus, 37.9 dB).
const MIN_PSNR_DB: f64 = 37.9;

/// The independent evaluator's JSON for `output` against `input`, with extra `flags`.
fn evaluate(input: &Path, output: &Path, flags: &[&str]) -> serde_json::Value {
    let evaluate =
        std::env::var_os("SCANATLAS_EVALUATE").expect("SCANATLAS_EVALUATE must name evaluate.py");
    let python = std::env::var_os("SCANATLAS_PYTHON").unwrap_or_else(|| "python3".into());
    let out = Command::new(python)
        .arg(evaluate)
        .arg(input)
        .arg(output)
        .args(flags)
        .output()
        .expect("python runs");
    assert!(out.status.success(), "evaluate.py failed: {}", String::from_utf8_lossy(&out.stderr));
    // Python writes an infinite PSNR (identical colours) as `Infinity` and a missing one as
    // `NaN`, which are not JSON: read them as the largest finite number and as null.
    let text = String::from_utf8(out.stdout).expect("evaluator prints UTF-8");
    let text =
        text.replace("-Infinity", "-1e308").replace("Infinity", "1e308").replace("NaN", "null");
    serde_json::from_str(&text).expect("evaluator prints JSON")
}

fn evaluator_input_stats(model: &Path) -> serde_json::Value {
    evaluate(model, model, &["--no-color", "--no-overlap"])["input"].clone()
}

/// The evaluator's comparison of `output` against `input`, texel overlaps and colour included
/// (colour costs about a second a model).
fn evaluator_comparison(input: &Path, output: &Path) -> serde_json::Value {
    evaluate(input, output, &[])
}

/// The evaluator's colour PSNR (dB) of the samples in `class` (`all`, `grid_preserved`,
/// `zero_uv_area`, ...), or `None` when the class has no sample.
fn psnr(v: &serde_json::Value, class: &str) -> Option<f64> {
    let c = &v["comparison"]["color"][class];
    if c["samples"].as_u64().unwrap_or(0) == 0 {
        return None;
    }
    Some(c["psnr_db"].as_f64().unwrap_or_else(|| panic!("{class}: no PSNR in {c}")))
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
            // OBJ and PLY have no scene graph: a glTF model goes out at its world positions (the
            // plane meal hangs under a turned node).
            let world = match ext {
                "obj" | "ply" => with_node_transforms(&input),
                _ => None,
            };
            assert_same_faces(world.as_ref().unwrap_or(&input), &back, ext.starts_with("gl"), tol);
        }
    }
}

/// The quantization step of decoded Draco values: Draco dequantizes component `c` to
/// `min_c + k·range/(2^bits − 1)`, one range for all components, so in a dense mesh the smallest
/// gap between distinct values of one component is the step (measured from the data, as the
/// decoder does not report its parameters).
fn lattice_step<const N: usize>(values: impl Iterator<Item = [f64; N]>) -> f64 {
    let mut per: [Vec<f64>; N] = std::array::from_fn(|_| Vec::new());
    for v in values {
        for (list, x) in per.iter_mut().zip(v) {
            list.push(x);
        }
    }
    let mut step = f64::INFINITY;
    for mut list in per {
        list.sort_by(f64::total_cmp);
        list.dedup();
        step = list.windows(2).map(|w| w[1] - w[0]).fold(step, f64::min);
    }
    step
}

/// Largest differences, corner by corner over the twin's faces in order, between a decoded
/// Draco model and its plain twin: (position, UV, normal), and the number of faces whose normals
/// could be compared (both sides carry them).
fn draco_twin_errors(
    draco: &scanatlas_core::model::Model,
    twin: &scanatlas_core::model::Model,
) -> ([f64; 3], usize) {
    let mut err = [0f64; 3];
    let mut with_normals = 0;
    for f in twin.face_ids() {
        let (a, b) = (draco.face_positions(f), twin.face_positions(f));
        let (ta, tb) = (draco.face_uvs(f).expect("draco UVs"), twin.face_uvs(f).expect("twin UVs"));
        let (fa, fb) = (&draco.faces[f.idx()], &twin.faces[f.idx()]);
        let normals = fa.n.zip(fb.n);
        with_normals += usize::from(normals.is_some());
        for c in 0..3 {
            for k in 0..3 {
                err[0] = err[0].max((a[c][k] - b[c][k]).abs());
                if let Some((na, nb)) = normals {
                    let (x, y) = (draco.normals[na[c].idx()][k], twin.normals[nb[c].idx()][k]);
                    err[2] = err[2].max(f64::from((x - y).abs()));
                }
            }
            for k in 0..2 {
                err[1] = err[1].max((ta[c][k] - tb[c][k]).abs());
            }
        }
    }
    (err, with_normals)
}

#[test]
fn draco_exports_read_and_match_their_decoded_twins() {
    let data = real_data();
    // (Draco file, its twin, faces of the Draco file the twin leaves out at the end).
    let cases = [
        ("venus-realitycapture/venus.gltf", "venus-realitycapture/venus.nodraco.gltf", 24_659),
        (
            "smithsonian-usnm1145291/usnm1145291.glb",
            "smithsonian-usnm1145291/usnm1145291.nodraco.gltf",
            0,
        ),
    ];
    for (draco_rel, twin_rel, extra) in cases {
        let t = Instant::now();
        let draco =
            read_model(&data.join(draco_rel)).unwrap_or_else(|e| panic!("{draco_rel}: {e}"));
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let twin = read_model(&data.join(twin_rel)).unwrap_or_else(|e| panic!("{twin_rel}: {e}"));
        assert_eq!(draco.faces.len(), twin.faces.len() + extra, "{draco_rel}: face count");
        let pos_step = lattice_step(draco.positions.iter().copied());
        // Only the UVs of textured faces: the others hold placeholders.
        let uv_step = lattice_step(draco.face_ids().filter_map(|f| draco.face_uvs(f)).flatten());
        let ([pos, uv, normal], with_normals) = draco_twin_errors(&draco, &twin);
        eprintln!(
            "{draco_rel}: read in {ms:.0} ms; max error position {pos:.3e} (step {:.3e}), UV {uv:.3e} (step {:.3e}), normal {normal:.3e} over {with_normals} of {} faces",
            pos_step,
            uv_step,
            twin.faces.len(),
        );
        assert!(pos <= pos_step, "{draco_rel}: position error {pos}");
        assert!(uv <= uv_step, "{draco_rel}: UV error {uv}");
        // Normals are octahedron-coded; both sides decode the same integers, so they agree to
        // f32 rounding (the twin stores what a decoder wrote).
        assert!(normal <= 1e-5, "{draco_rel}: normal error {normal}");
    }
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

/// Prepares and merges one real model with the defaults (`paper`, `arap`) and checks the result
/// independently. Every model is checked before any assertion, so one failing model does not hide
/// the figures of the others.
#[test]
fn real_models_merge_without_new_flips_overlaps_or_excess_distortion() {
    use scanatlas_core::defrag::{MergeOptions, merge_charts, merged_model};
    use scanatlas_core::plugin::{Params, Registry};
    use scanatlas_core::topology::Topology;
    let mut reg = Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    let data = real_data();
    let mut failures = Vec::new();
    for rel in MODELS {
        let model = pipeline::load_model(&data.join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"));
        let scorer = reg.scorer("paper", &Params::new()).unwrap();
        let mut solver = reg.solver("arap", &Params::new()).unwrap();
        let t = Instant::now();
        let mut topo = Topology::build(&model, &pipeline::sheet_sizes(&model))
            .unwrap_or_else(|e| panic!("{rel}: {e}"));
        let prepare_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let (report, _) =
            merge_charts(&mut topo, scorer.as_ref(), solver.as_mut(), &MergeOptions::default())
                .unwrap();
        let merge_s = t.elapsed().as_secs_f64();
        let out = merged_model(&model, &topo);
        let t = Instant::now();
        let c = check(&model, &out);
        let check_s = t.elapsed().as_secs_f64();
        println!(
            "{rel}: {} faces, charts {} → {} ({} across sheets; engine {} → {}), border {:.0} → {:.0} texels, \
             new flips {} {:?}, new overlaps {} {:?}, old overlaps {}, distortion {:.5} \
             (engine {:.5}); prepare {prepare_s:.1} s, merge {merge_s:.1} s, check {check_s:.1} s",
            model.faces.len(),
            c.input.charts,
            c.output.charts,
            c.output.charts_across_sheets,
            report.charts_before,
            report.charts_after,
            c.input.border_length,
            c.output.border_length,
            c.new_flips,
            c.new_flip_faces,
            c.new_overlaps,
            c.new_overlap_pairs,
            c.old_overlaps,
            c.distortion,
            report.energy_after,
        );
        if !c.faces_kept() {
            failures.push(format!("{rel}: {} faces changed", c.changed_faces));
        }
        if c.new_flips > 0 {
            failures
                .push(format!("{rel}: {} new flips, first {:?}", c.new_flips, c.new_flip_faces));
        }
        if c.new_overlaps > 0 {
            failures.push(format!(
                "{rel}: {} new overlaps, first {:?}",
                c.new_overlaps, c.new_overlap_pairs
            ));
        }
        if c.distortion > 0.025 {
            failures.push(format!("{rel}: distortion {} > 0.025", c.distortion));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Whole `defrag` runs judged by the independent evaluator: every face kept, and no new flipped,
/// degenerate or overlapping faces (two faces on one texel centre they did not share in the
/// input). `arap` on the three models, `slim` on the two smaller ones, and meshroom with the
/// patch budget α = 10: there an inherited fold leaves texel clashes the sub-texel moves cannot
/// separate, so the faces are cut out of their chart.
#[test]
fn real_models_defragment_without_new_flips_degenerate_faces_or_texel_overlaps() {
    let mut reg = scanatlas_core::plugin::Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    let data = real_data();
    let dir = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    let runs = MODELS.iter().map(|m| (*m, "arap", 5.0)).chain([
        (MODELS[1], "slim", 5.0),
        (MODELS[2], "slim", 5.0),
        (MODELS[1], "arap", 10.0),
    ]);
    for (i, (rel, solver, alpha)) in runs.enumerate() {
        let input = data.join(rel);
        // Each model is written in its own format: glTF stores UVs as f32, whose rounding alone
        // once turned 50 slivers of venus over.
        let ext = input.extension().and_then(|e| e.to_str()).unwrap_or("obj");
        let output = dir.path().join(format!("out{i}.{ext}"));
        let mut cfg =
            pipeline::defrag::DefragConfig { solver: solver.into(), ..Default::default() };
        assert_eq!(cfg.merge.alpha, 5.0, "the default α");
        cfg.merge.alpha = alpha;
        let t = Instant::now();
        let report = pipeline::defrag::defrag(&input, &output, &reg, &cfg)
            .unwrap_or_else(|e| panic!("{rel} ({solver}): {e}"));
        let run_s = t.elapsed().as_secs_f64();
        let v = evaluator_comparison(&input, &output);
        let c = &v["comparison"];
        let degenerate = c["new_degenerate_faces"].as_i64().unwrap();
        let figures = [
            (
                "faces in - out",
                v["input"]["faces"].as_i64().unwrap() - v["output"]["faces"].as_i64().unwrap(),
            ),
            ("new flipped faces", c["new_flipped_faces"].as_i64().unwrap()),
            ("new degenerate faces but specks", (degenerate - specks(&report)).max(0)),
            (
                "new overlapping face pairs",
                c["overlap"]["new_overlap_face_pairs"].as_i64().unwrap(),
            ),
        ];
        let colour = psnr(&v, "all").expect("colour samples");
        println!(
            "{rel} ({solver}, α {alpha}): {run_s:.1} s, {} charts, PSNR {colour:.2} dB, texel \
             clashes separated {} of {}, faces detached {}, {figures:?}",
            v["output"]["charts"],
            report.pack.as_ref().map_or(0, |p| p.texel_clashes - p.texel_clashes_left),
            report.pack.as_ref().map_or(0, |p| p.texel_clashes),
            report.pack.as_ref().map_or(0, |p| p.faces_detached),
        );
        for (what, n) in figures {
            if n != 0 {
                failures.push(format!("{rel} ({solver}, α {alpha}): {what} = {n}"));
            }
        }
        if colour < MIN_PSNR_DB {
            failures.push(format!("{rel} ({solver}, α {alpha}): PSNR {colour} dB"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The faces a run made point faces on purpose (see `PackOptions::speck_area`): the only new
/// degenerate faces allowed.
fn specks(report: &pipeline::defrag::DefragReport) -> i64 {
    report.pack.as_ref().map_or(0, |p| p.palette.speck_faces as i64)
}

/// Fixed power-of-two sheets (`--sheet-size 2048 --pow2`) on meshroom and the plane: every
/// output sheet is 2048², every face is kept, and the independent evaluator finds no new flip,
/// degenerate face or texel overlap.
#[test]
fn fixed_power_of_two_sheets_are_valid_on_meshroom_and_the_plane() {
    let mut reg = scanatlas_core::plugin::Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    let data = real_data();
    let dir = tempfile::tempdir().unwrap();
    for (i, rel) in [MODELS[1], MODELS[2]].into_iter().enumerate() {
        let input = data.join(rel);
        let ext = input.extension().and_then(|e| e.to_str()).unwrap_or("obj");
        let output = dir.path().join(format!("fixed{i}.{ext}"));
        let mut cfg = pipeline::defrag::DefragConfig::default();
        cfg.pack.sheet_size = Some((2048, 2048));
        cfg.pack.pow2 = true;
        let report = pipeline::defrag::defrag(&input, &output, &reg, &cfg)
            .unwrap_or_else(|e| panic!("{rel}: {e}"));
        let specks = specks(&report);
        let sizes: Vec<_> =
            report.output_stats.texture_sizes.iter().map(|s| (s.width, s.height)).collect();
        let fixed = (Some(2048), Some(2048));
        assert!(!sizes.is_empty() && sizes.iter().all(|&s| s == fixed), "{rel}: {sizes:?}");
        let v = evaluator_comparison(&input, &output);
        let c = &v["comparison"];
        println!("{rel}: {} sheets of 2048², evaluator {c}", sizes.len());
        assert_eq!(v["input"]["faces"], v["output"]["faces"], "{rel}: lost faces");
        assert_eq!(v["output"]["faces_without_uv"], 0, "{rel}");
        assert_eq!(c["new_flipped_faces"], 0, "{rel}: new flips");
        let degenerate = c["new_degenerate_faces"].as_i64().unwrap();
        assert!(degenerate <= specks, "{rel}: {degenerate} new degenerate faces, {specks} specks");
        assert_eq!(c["overlap"]["new_overlap_face_pairs"], 0, "{rel}: new overlaps");
    }
}

/// The glTF document of a `.gltf` or `.glb` file.
fn gltf_json(path: &Path) -> serde_json::Value {
    let bytes = std::fs::read(path).unwrap();
    if bytes.starts_with(b"glTF") {
        let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        return serde_json::from_slice(&bytes[20..20 + len]).unwrap();
    }
    serde_json::from_slice(&bytes).unwrap()
}

/// Every map of a material follows the atlas (issue 37 §8): on the wooden letter (colour and
/// normal PNGs) and the Smithsonian scan (Draco GLB and its plain twin; colour, occlusion and
/// normal JPEGs), every output material has each of the input's maps, every image the output
/// refers to is one the run wrote, and the material properties are the input's.
#[test]
fn every_map_of_a_material_follows_the_atlas_on_real_exports() {
    let mut reg = scanatlas_core::plugin::Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    let data = real_data();
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &str, &[&str]); 3] = [
        ("sketchfab-wooden-letter/scene.gltf", "gltf", &["normalTexture"]),
        ("smithsonian-usnm1145291/usnm1145291.glb", "glb", &["normalTexture", "occlusionTexture"]),
        (
            "smithsonian-usnm1145291/usnm1145291.nodraco.gltf",
            "gltf",
            &["normalTexture", "occlusionTexture"],
        ),
    ];
    for (i, (rel, ext, roles)) in cases.into_iter().enumerate() {
        let input = data.join(rel);
        let out_dir = dir.path().join(format!("case{i}"));
        std::fs::create_dir_all(&out_dir).unwrap();
        let output = out_dir.join(format!("out.{ext}"));
        let cfg = pipeline::defrag::DefragConfig::default();
        let report = pipeline::defrag::defrag(&input, &output, &reg, &cfg)
            .unwrap_or_else(|e| panic!("{rel}: {e}"));
        let doc = gltf_json(&output);
        let original = &gltf_json(&input)["materials"][0];
        let materials = doc["materials"].as_array().unwrap();
        println!("{rel}: {} materials, maps {:?}", materials.len(), report.maps);
        assert_eq!(report.maps.len(), materials.len() * roles.len(), "{rel}: {:?}", report.maps);
        for (k, m) in materials.iter().enumerate() {
            for key in ["doubleSided", "alphaMode"] {
                assert_eq!(m.get(key), original.get(key), "{rel}: material {k} {key}");
            }
            let pbr = &m["pbrMetallicRoughness"];
            for key in ["roughnessFactor", "metallicFactor", "baseColorFactor"] {
                let want = original["pbrMetallicRoughness"].get(key);
                assert_eq!(pbr.get(key), want, "{rel}: material {k} {key}");
            }
            for role in roles.iter() {
                assert!(m[*role]["index"].is_u64(), "{rel}: material {k} has no {role}: {m}");
            }
        }
        for (k, image) in doc["images"].as_array().unwrap().iter().enumerate() {
            match image.get("uri").and_then(|u| u.as_str()) {
                Some(uri) => {
                    let path = out_dir.join(uri);
                    assert!(path.exists(), "{rel}: image {k} {uri} missing");
                    let written = report.sheets.iter().chain(report.maps.iter().map(|m| &m.path));
                    let ours = written.map(|p| p.canonicalize().unwrap()).collect::<Vec<_>>();
                    assert!(ours.contains(&path.canonicalize().unwrap()), "{rel}: image {uri}");
                }
                None => assert!(image["bufferView"].is_u64(), "{rel}: image {k}"),
            }
        }
        if ext == "glb" {
            assert_eq!(doc["images"].as_array().unwrap().len(), 1 + roles.len(), "{rel}");
        }
    }
}

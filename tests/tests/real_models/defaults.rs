//! `defrag` with every default (`paper` scorer, `arap+slim` solver, `horizon` packer, padding 4)
//! on the real models, judged by the independent evaluator with colour, against floors taken
//! from the reference's figures (`../shared/tools/README.md`, MeshLab's texture defragmentation)
//! where we meet them, and from today's figures, with the goal named, where we do not yet.

use std::time::Instant;

use scanatlas_core::pipeline;
use scanatlas_tests::real_data;

use super::{evaluator_comparison, psnr};

/// The floors one model's default run must meet.
struct Floors {
    rel: &'static str,
    /// Most output charts that cover UV area (`charts_edge_with_area`).
    max_charts: i64,
    /// Least atlas solidity (UV area over the area of the charts' hulls, as the evaluator has it).
    min_solidity: f64,
    /// Least share of the 3-D area whose texels are copied on the texel grid.
    min_preserved_area: f64,
    /// Least colour PSNR (dB) against the input, over all samples and over the preserved faces.
    min_psnr: f64,
    min_preserved_psnr: f64,
    /// Least colour PSNR of the faces without UV area, where the model has any.
    min_zero_uv_psnr: f64,
    /// Most new flipped faces: 0 but where a known bug is pending.
    max_new_flips: i64,
}

/// The distortion budget g of the defaults: the evaluator's mean ARAP energy of the written UVs
/// against the input's must not exceed it.
const BUDGET: f64 = 0.025;

/// The floors: the reference's figures where we meet them (`../shared/tools/README.md`), else the
/// figures this suite was last calibrated on (history in `benches/results/`), with the goal named.
/// A change of the merge's path moves the calibrated figures both ways at once; each
/// recalibration and what it traded is recorded there.
/// The goal for the preserved faces' PSNR is 60 dB, which no model meets yet (see
/// `docs/FIDELITY.md` for why).
const FLOORS: [Floors; 4] = [
    // The reference's figures.
    Floors {
        rel: "meshroom-esp32cam/texturedMesh.obj",
        max_charts: 79,
        min_solidity: 0.124,
        min_preserved_area: 0.083,
        min_psnr: 41.2,
        // FIXME: goal 60 dB.
        min_preserved_psnr: 50.9,
        min_zero_uv_psnr: 35.0,
        max_new_flips: 0,
    },
    // The reference crashes on the plane: every floor is a calibrated figure.
    Floors {
        rel: "sketchfab-plane-meal/scene.gltf",
        max_charts: 61,
        min_solidity: 0.0911,
        min_preserved_area: 0.27,
        min_psnr: 46.3,
        // FIXME: goal 60 dB.
        min_preserved_psnr: 48.3,
        min_zero_uv_psnr: 35.0,
        max_new_flips: 0,
    },
    // The reference's figures.
    Floors {
        rel: "venus-realitycapture/venus.nodraco.gltf",
        max_charts: 516,
        min_solidity: 0.0269,
        min_preserved_area: 0.605,
        min_psnr: 37.9,
        // FIXME: goal 60 dB.
        min_preserved_psnr: 44.4,
        min_zero_uv_psnr: 35.0,
        max_new_flips: 0,
    },
    // The reference aborts on the Smithsonian model: every floor is a calibrated figure.
    Floors {
        rel: "smithsonian-usnm1145291/usnm1145291.nodraco.gltf",
        max_charts: 634,
        min_solidity: 0.0317,
        min_preserved_area: 0.44,
        min_psnr: 44.3,
        // FIXME: goal 60 dB.
        min_preserved_psnr: 47.3,
        // The evaluator's default draws few samples on these faces, and with many more the figure
        // is lower: the slivers held inside charts by an edge keep an error. FIXME: 35 dB there.
        min_zero_uv_psnr: 36.0,
        max_new_flips: 0,
    },
];

/// Each figure of `v` against `floor`, as failure messages; `specks` is how many faces the run
/// made point faces on purpose (`pack.palette.speck_faces`), the only new degenerate faces allowed.
fn shortfalls(floor: &Floors, v: &serde_json::Value, specks: usize) -> Vec<String> {
    let (input, output, c) = (&v["input"], &v["output"], &v["comparison"]);
    let int = |x: &serde_json::Value| x.as_i64().unwrap_or_else(|| panic!("not an integer: {x}"));
    let real = |x: &serde_json::Value| x.as_f64().unwrap_or_else(|| panic!("not a number: {x}"));
    let charts = int(&output["charts_edge_with_area"]);
    let mut out = Vec::new();
    let mut check = |ok: bool, what: String| {
        if !ok {
            out.push(format!("{}: {what}", floor.rel));
        }
    };
    check(int(&input["faces"]) == int(&output["faces"]), format!("faces lost: {v}"));
    check(
        int(&output["faces_without_uv"]) == int(&input["faces_without_uv"]),
        "faces without UVs".into(),
    );
    let flips = int(&c["new_flipped_faces"]);
    check(flips <= floor.max_new_flips, format!("{flips} new flipped faces"));
    let degenerate = int(&c["new_degenerate_faces"]);
    check(
        degenerate <= specks as i64,
        format!("{degenerate} new degenerate faces, {specks} specks"),
    );
    let pairs = int(&c["overlap"]["new_overlap_face_pairs"]);
    check(pairs == 0, format!("{pairs} new overlapping face pairs"));
    check(charts < int(&input["charts_edge_with_area"]), format!("no chart merged ({charts})"));
    check(charts <= floor.max_charts, format!("{charts} charts with area > {}", floor.max_charts));
    let energy = real(&c["distortion_arap"]["mean"]);
    check(energy <= BUDGET, format!("mean ARAP energy {energy} over the budget {BUDGET}"));
    let solidity = real(&output["atlas_solidity"]);
    check(solidity >= floor.min_solidity, format!("solidity {solidity} < {}", floor.min_solidity));
    let preserved = real(&c["grid_preserved"]["area3d_fraction"]);
    let min = floor.min_preserved_area;
    check(preserved >= min, format!("grid-preserved area {preserved} < {min}"));
    let all = psnr(v, "all").expect("colour samples");
    check(all >= floor.min_psnr, format!("PSNR {all} dB < {}", floor.min_psnr));
    let kept = psnr(v, "grid_preserved").expect("preserved samples");
    let min = floor.min_preserved_psnr;
    check(kept >= min, format!("preserved faces' PSNR {kept} dB < {min}"));
    if let Some(zero) = psnr(v, "zero_uv_area") {
        let min = floor.min_zero_uv_psnr;
        check(zero >= min, format!("zero-UV faces' PSNR {zero} dB < {min}"));
    }
    out
}

/// The default run on meshroom, the plane, venus and the Smithsonian model meets its floors, and
/// keeps every face without a new defect. Every model is run before any assertion.
#[test]
fn default_defrag_meets_the_reference_figures_with_colour() {
    let mut reg = scanatlas_core::plugin::Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    let data = real_data();
    let dir = tempfile::tempdir().unwrap();
    let cfg = pipeline::defrag::DefragConfig::default();
    assert_eq!((cfg.solver.as_str(), cfg.pack.padding), ("arap+slim", 4), "the defaults");
    let mut failures = Vec::new();
    for (i, floor) in FLOORS.iter().enumerate() {
        let input = data.join(floor.rel);
        let ext = input.extension().and_then(|e| e.to_str()).unwrap_or("obj");
        let output = dir.path().join(format!("default{i}.{ext}"));
        let t = Instant::now();
        let report = pipeline::defrag::defrag(&input, &output, &reg, &cfg)
            .unwrap_or_else(|e| panic!("{}: {e}", floor.rel));
        let specks = report.pack.as_ref().map_or(0, |p| p.palette.speck_faces);
        let run_s = t.elapsed().as_secs_f64();
        let v = evaluator_comparison(&input, &output);
        let c = &v["comparison"];
        println!(
            "{}: {run_s:.1} s; charts with area {} → {}, solidity {}, grid-preserved {:.4}, PSNR \
             all {:?} / preserved {:?} / zero-UV {:?} dB, mean ARAP {}, new flips {}, new \
             overlapping pairs {}",
            floor.rel,
            v["input"]["charts_edge_with_area"],
            v["output"]["charts_edge_with_area"],
            v["output"]["atlas_solidity"],
            c["grid_preserved"]["area3d_fraction"],
            psnr(&v, "all"),
            psnr(&v, "grid_preserved"),
            psnr(&v, "zero_uv_area"),
            c["distortion_arap"]["mean"],
            c["new_flipped_faces"],
            c["overlap"]["new_overlap_face_pairs"],
        );
        failures.extend(shortfalls(floor, &v, specks));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

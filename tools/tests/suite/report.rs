//! The HTML report through the `scanatlas` binary: `defrag --report-dir` on a synthetic scan,
//! `scanatlas report` of a model against itself (everything copied, identical colours) and against
//! another mesh (refused), the folder rules, and `--progress json`.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::scanatlas;

#[track_caller]
fn ok(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    stderr
}

fn synth(d: &Path, name: &str, seed: &str) -> PathBuf {
    let args =
        ["synth", name, "--faces", "3000", "--sheets", "2", "--sheet-size", "256", "--seed", seed];
    ok(&scanatlas(&args, d));
    d.join(name).join("scan.obj")
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

fn png_size(path: &Path) -> (u32, u32) {
    let d = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let r = d.read_info().unwrap();
    (r.info().width, r.info().height)
}

#[test]
fn defrag_report_dir_writes_pictures_plots_and_figures() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = synth(d, "scan", "3");
    let args = ["defrag", input.to_str().unwrap(), "-o", "out/out.obj", "--report-dir", "rep"];
    let stderr = ok(&scanatlas(&[&args[..], &["--preview-size", "128"]].concat(), d));
    // The terminal headline: sheet sizes with the texel change, and the report's own line.
    assert!(stderr.contains("2 × 256² → "), "{stderr}");
    assert!(stderr.contains("% texels)") && stderr.contains("report rep/index.html: "), "{stderr}");

    let r = json(&d.join("rep/report.json"));
    let f = &r["report"]["figures"];
    let (before, after) = (&f["before"], &f["after"]);
    assert!(after["charts"].as_u64() < before["charts"].as_u64(), "{f}");
    let copied = f["preserved_area_fraction"].as_f64().unwrap();
    assert!(copied > 0.0 && copied <= 1.0, "{copied}");
    let psnr = f["colour"]["all"]["psnr_db"].as_f64().unwrap();
    assert!(psnr > 25.0, "colour PSNR {psnr}");
    assert_eq!(f["faces_lost"], 0);
    assert!(r["run"]["merge"]["attempted"].as_u64().unwrap() > 0, "the run's report is kept");

    let html = std::fs::read_to_string(d.join("rep/index.html")).unwrap();
    assert!(html.contains(f["headline"].as_str().unwrap()));
    for sheets in ["before_sheets", "after_sheets"] {
        for s in r["report"][sheets].as_array().unwrap() {
            let atlas = s["atlas"].as_str().unwrap();
            let (w, h) = png_size(&d.join("rep").join(atlas));
            assert!(w <= 128 && h <= 128 && w.max(h) >= 64, "{atlas}: {w}x{h}");
            assert!(html.contains(atlas));
            assert!(d.join("rep").join(s["texture"].as_str().unwrap()).is_file());
        }
    }
    let svg = std::fs::read_to_string(d.join("rep/chart_sizes.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("faces per chart"));
    assert!(d.join("rep/distortion.svg").is_file());
    // Nothing is left beside the report but the output and the inputs.
    let mut names: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["out", "rep", "scan"]);
}

#[test]
fn a_model_against_itself_is_all_copied_with_identical_colours() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = synth(d, "scan", "5");
    let p = input.to_str().unwrap();
    let stderr = ok(&scanatlas(&["report", p, p, "-o", "rep", "--preview-size", "64"], d));
    assert!(stderr.contains("100% of the surface copied texel for texel"), "{stderr}");
    assert!(stderr.contains("colours identical to the input"), "{stderr}");
    let f = json(&d.join("rep/report.json"))["report"]["figures"].clone();
    assert_eq!(f["mean_distortion"], 0.0);
    // A second report replaces the first; a folder holding something else is refused.
    ok(&scanatlas(&["report", p, p, "-o", "rep", "--colour-samples", "0"], d));
    assert!(json(&d.join("rep/report.json"))["report"]["figures"]["colour"].is_null());
    std::fs::create_dir(d.join("busy")).unwrap();
    std::fs::write(d.join("busy/notes.txt"), "mine").unwrap();
    let out = scanatlas(&["report", p, p, "-o", "busy"], d);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("does not hold a scanatlas report"));
    assert_eq!(std::fs::read_to_string(d.join("busy/notes.txt")).unwrap(), "mine");
}

#[test]
fn another_mesh_is_refused_with_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = synth(d, "a", "1");
    let b = synth(d, "b", "2");
    let out = scanatlas(&["report", a.to_str().unwrap(), b.to_str().unwrap(), "-o", "rep"], d);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("not the same mesh") && !stderr.contains("panicked"), "{stderr}");
    assert!(!d.join("rep").exists());
}

#[test]
fn progress_json_streams_one_line_per_stage_event() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = synth(d, "scan", "4");
    let args = ["--progress", "json", "defrag", input.to_str().unwrap(), "-o", "out/out.obj", "-q"];
    let stderr = ok(&scanatlas(&args, d));
    let events: Vec<serde_json::Value> =
        stderr.lines().map(|l| serde_json::from_str(l).expect("every line is JSON")).collect();
    let merge: Vec<_> = events.iter().filter(|e| e["stage"] == "merging charts").collect();
    assert_eq!(merge.first().map(|e| &e["event"]), Some(&serde_json::json!("start")));
    assert!(merge.last().unwrap()["seconds"].as_f64().is_some(), "{merge:?}");
    // Without it, --quiet and a pipe print nothing at all.
    let quiet = ["defrag", input.to_str().unwrap(), "-o", "out2/out.obj", "-q"];
    assert_eq!(ok(&scanatlas(&quiet, d)), "");
}

/// Collapses every `step`-th face of an OBJ onto one UV point: the UV of a corner of the face
/// half the model away (a point the face's 3-D neighbours do not hold), as exporters collapse
/// faces no camera saw. The new `vt` lines go after the last one.
fn collapse_faces_to_points(obj: &Path, step: usize) -> usize {
    let text = std::fs::read_to_string(obj).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let faces: Vec<usize> = (0..lines.len()).filter(|&i| lines[i].starts_with("f ")).collect();
    let n_vt = lines.iter().filter(|l| l.starts_with("vt ")).count();
    let last_vt = lines.iter().rposition(|l| l.starts_with("vt ")).unwrap();
    let vt_of =
        |line: &str| line.split_whitespace().nth(1).unwrap().split('/').nth(1).unwrap().to_string();
    let vts: Vec<&str> = lines.iter().filter(|l| l.starts_with("vt ")).copied().collect();
    let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let mut added = Vec::new();
    for (k, &i) in faces.iter().enumerate().filter(|(k, _)| k % step == 0) {
        let far = faces[(k + faces.len() / 2) % faces.len()];
        let vt: usize = vt_of(lines[far]).parse().unwrap();
        added.push(vts[vt - 1].to_string());
        let id = n_vt + added.len();
        let corners: Vec<String> = lines[i]
            .split_whitespace()
            .skip(1)
            .map(|c| {
                let mut p: Vec<String> = c.split('/').map(str::to_string).collect();
                p[1] = id.to_string();
                p.join("/")
            })
            .collect();
        out[i] = format!("f {}", corners.join(" "));
    }
    let n = added.len();
    out.splice(last_vt + 1..last_vt + 1, added);
    std::fs::write(obj, out.join("\n") + "\n").unwrap();
    n
}

#[test]
fn faces_without_input_uv_area_keep_their_colour() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = synth(d, "scan", "5");
    let collapsed = collapse_faces_to_points(&input, 25);
    assert!(collapsed > 100, "{collapsed}");
    for format in ["png", "jpg"] {
        let out = format!("out_{format}/out.obj");
        let rep = format!("rep_{format}");
        let args = ["defrag", input.to_str().unwrap(), "-o", &out, "--report-dir", &rep];
        let fmt = ["--texture-format", format, "--preview-size", "64"];
        ok(&scanatlas(&[&args[..], &fmt[..]].concat(), d));
        let r = json(&d.join(&rep).join("report.json"));
        let f = &r["report"]["figures"];
        let points = &f["colour"]["zero_uv_area"];
        assert!(points["samples"].as_u64().unwrap() > 200, "{f}");
        let psnr = points["psnr_db"].as_f64().unwrap();
        assert!(psnr >= 40.0, "{format}: colour PSNR of the faces without UV area {psnr}");
        // Counted apart: every collapsed face is a point face of the output, none a chart.
        assert_eq!(f["after"]["point_faces"].as_u64(), Some(collapsed as u64), "{f}");
        let pal = &r["run"]["pack"]["palette"];
        assert_eq!(pal["point_faces"].as_u64(), Some(collapsed as u64), "{pal}");
        assert!(pal["blocks"].as_u64().unwrap() <= collapsed as u64, "{pal}");
    }
}

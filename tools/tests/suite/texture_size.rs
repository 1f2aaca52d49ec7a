//! End-to-end tests of the texture-size options of `defrag`: fixed sheets (`--sheet-size`),
//! power-of-two and aligned sides (`--pow2`, `--align`), the texel scale (`--texel-scale`) with
//! its warning, the same options from a `--config` file, and their refusal before any work.

use std::path::Path;
use std::process::Output;

use crate::common::scanatlas;

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A synthetic scan `s/scan.obj` of two 256² sheets in `d`.
fn synth(d: &Path) {
    let out =
        scanatlas(&["synth", "s", "--faces", "3000", "--sheet-size", "256", "--sheets", "2"], d);
    assert!(out.status.success(), "{}", stderr(&out));
}

/// Runs `defrag s/scan.obj -o DIR/out.EXT --report DIR/r.json EXTRA…` and returns the report.
fn defrag(d: &Path, output: &str, extra: &[&str]) -> serde_json::Value {
    let report = Path::new(output).with_file_name("r.json");
    let report = report.to_str().unwrap();
    let mut args = vec!["defrag", "s/scan.obj", "-o", output, "--report", report, "-q"];
    args.extend_from_slice(extra);
    let out = scanatlas(&args, d);
    assert!(out.status.success(), "{extra:?}: {}", stderr(&out));
    serde_json::from_slice(&std::fs::read(d.join(report)).unwrap()).unwrap()
}

/// The output sheet sizes the output's own statistics give (read back from the files).
fn sheet_sizes(r: &serde_json::Value) -> Vec<(u64, u64)> {
    let sizes = r["output_stats"]["texture_sizes"].as_array().unwrap();
    sizes.iter().map(|s| (s["width"].as_u64().unwrap(), s["height"].as_u64().unwrap())).collect()
}

/// No face lost, no UV flip or overlap in the output, every face on a sheet.
#[track_caller]
fn assert_valid(r: &serde_json::Value) {
    let o = &r["output_stats"];
    assert_eq!(o["faces"], r["input_stats"]["faces"]);
    assert_eq!(r["faces_unpacked"].as_u64(), Some(0));
    assert_eq!(o["uv_flipped_faces"].as_u64(), Some(0));
    assert_eq!(o["overlap_face_pairs"].as_u64(), Some(0));
    assert_eq!(o["uv_out_of_unit_faces"].as_u64(), Some(0));
}

fn codes(r: &serde_json::Value) -> Vec<String> {
    let w = r["warnings"].as_array().unwrap();
    w.iter().map(|w| w["code"].as_str().unwrap().to_string()).collect()
}

#[test]
fn fixed_power_of_two_sheets_are_filled_and_all_of_that_size() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d);
    for output in ["o/out.obj", "g/out.glb"] {
        let r = defrag(d, output, &["--sheet-size", "128", "--pow2"]);
        assert_valid(&r);
        let sizes = sheet_sizes(&r);
        // Two 256² input sheets cannot go on one 128² sheet.
        assert!(sizes.len() >= 2, "{sizes:?}");
        assert!(sizes.iter().all(|&s| s == (128, 128)), "{sizes:?}");
        assert_eq!(r["pack"]["sheets_off_size"].as_u64(), Some(0));
        // At a texel scale of 1 texels are still copied verbatim.
        assert!(r["pack"]["preserved_faces"].as_u64().unwrap() > 0);
        assert!(codes(&r).is_empty(), "{:?}", r["warnings"]);
    }
    // A non-square fixed size is kept as given.
    let r = defrag(d, "w/out.obj", &["--sheet-size", "256x128"]);
    assert_valid(&r);
    assert!(sheet_sizes(&r).iter().all(|&s| s == (256, 128)), "{:?}", sheet_sizes(&r));
}

#[test]
fn trimmed_sheets_round_up_to_powers_of_two_or_multiples() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d);
    let r = defrag(d, "p/out.obj", &["--pow2", "--max-sheet-size", "200"]);
    assert_valid(&r);
    // The limit 200 is rounded down to 128, so no side passes what the user allowed.
    for (w, h) in sheet_sizes(&r) {
        assert!(w.is_power_of_two() && h.is_power_of_two() && w <= 128 && h <= 128, "{w}x{h}");
    }
    let r = defrag(d, "a/out.obj", &["--align", "24"]);
    assert_valid(&r);
    for (w, h) in sheet_sizes(&r) {
        assert!(w % 24 == 0 && h % 24 == 0, "{w}x{h}");
    }
}

#[test]
fn a_texel_scale_below_one_resamples_everything_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d);
    let full = defrag(d, "f/out.obj", &[]);
    let args = ["defrag", "s/scan.obj", "-o", "h/out.obj", "--report", "h/r.json"];
    let out = scanatlas(&[&args[..], &["--texel-scale", "0.5"]].concat(), d);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("warning: --texel-scale 0.5"), "{}", stderr(&out));
    let half: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("h/r.json")).unwrap()).unwrap();
    assert_valid(&half);
    assert_eq!(codes(&half), ["texel-scale-below-one"]);
    assert_eq!(half["pack"]["preserved_faces"].as_u64(), Some(0));
    assert_eq!(half["pack_options"]["texel_scale"].as_f64(), Some(0.5));
    // Every chart's area shrinks to a quarter; padding and packing keep the sheets above that.
    let texels = |r: &serde_json::Value| r["output_stats"]["uv_area_texels"].as_f64().unwrap();
    let ratio = texels(&half) / texels(&full);
    assert!((0.2..0.3).contains(&ratio), "UV area ratio {ratio}");
    // With --strict the warning fails the run before anything is written.
    let out = scanatlas(
        &["defrag", "s/scan.obj", "-o", "x/out.obj", "--texel-scale", "0.5", "--strict"],
        d,
    );
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("texel-scale-below-one"), "{}", stderr(&out));
    assert!(!d.join("x/out.obj").exists());
    // Above one there is no warning, and the charts grow.
    let double = defrag(d, "d/out.obj", &["--texel-scale", "2"]);
    assert_valid(&double);
    assert!(codes(&double).is_empty(), "{:?}", double["warnings"]);
    let ratio = texels(&double) / texels(&full);
    assert!((3.5..4.5).contains(&ratio), "UV area ratio {ratio}");
}

#[test]
fn the_options_and_the_texture_format_come_from_a_config_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d);
    let text = "sheet-size = 128\npow2 = true\ntexture-format = \"jpg\"\ntexel-scale = 1.0\n";
    std::fs::write(d.join("c.toml"), text).unwrap();
    let r = defrag(d, "c/out.obj", &["--config", "c.toml"]);
    assert_valid(&r);
    assert!(sheet_sizes(&r).iter().all(|&s| s == (128, 128)), "{:?}", sheet_sizes(&r));
    assert!(d.join("c/out_0.jpg").exists());
    // The command line wins over the file.
    let r = defrag(
        d,
        "m/out.obj",
        &["--config", "c.toml", "--sheet-size", "256", "--texture-format", "png"],
    );
    assert!(sheet_sizes(&r).iter().all(|&s| s == (256, 256)), "{:?}", sheet_sizes(&r));
    assert!(d.join("m/out_0.png").exists());
}

#[test]
fn impossible_sizes_are_refused_as_bad_usage_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d);
    let cases: [(&[&str], &str); 11] = [
        (&["--sheet-size", "1000", "--pow2"], "try 1024x1024"),
        (&["--sheet-size", "100", "--align", "16"], "--align 16"),
        (&["--pow2", "--align", "12"], "--align 12"),
        (&["--align", "0"], "--align"),
        (&["--texel-scale", "0"], "--texel-scale"),
        (&["--texel-scale", "100"], "--texel-scale"),
        (&["--texel-scale", "NaN"], "--texel-scale"),
        (&["--max-sheet-size", "10", "--align", "16"], "--max-sheet-size"),
        (&["--sheet-size", "128", "--max-sheet-size", "256"], "--max-sheet-size"),
        (&["--sheet-size", "16384", "--texture-format", "webp"], "at most 16383"),
        (&["--max-sheet-size", "20000", "--texture-format", "webp-lossy"], "at most 16383"),
    ];
    for (extra, needle) in cases {
        let args = [&["defrag", "s/scan.obj", "-o", "x/out.obj"][..], extra].concat();
        let out = scanatlas(&args, d);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {}", stderr(&out));
        assert!(stderr(&out).contains(needle), "{extra:?}: {}", stderr(&out));
        assert!(!stderr(&out).contains("panicked"), "{}", stderr(&out));
        assert!(!d.join("x").exists(), "{extra:?} left an output folder");
    }
    for (text, needle) in [
        ("texture-format = \"gif\"\n", "gif"),
        ("sheet-size = \"12y4\"\n", "sheet-size"),
        ("align = -3\n", "align"),
        ("pow2 = 1\n", "pow2"),
    ] {
        std::fs::write(d.join("bad.toml"), text).unwrap();
        let out =
            scanatlas(&["defrag", "s/scan.obj", "-o", "x/out.obj", "--config", "bad.toml"], d);
        assert_eq!(out.status.code(), Some(2), "{text}: {}", stderr(&out));
        assert!(stderr(&out).contains(needle), "{text}: {}", stderr(&out));
    }
}

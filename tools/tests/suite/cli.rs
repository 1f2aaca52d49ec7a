//! End-to-end tests of the `scanatlas` binary: exit codes, one-line errors on bad input (never a
//! panic), and the zero-input commands.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::scanatlas;

/// Asserts a clean failure: exit status 1, an error line naming `needle`, no panic.
#[track_caller]
fn assert_clean_failure(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "panic on bad input: {stderr}");
    assert!(stderr.contains("scanatlas: error:"), "stderr: {stderr}");
    assert!(stderr.contains(needle), "error does not mention {needle:?}: {stderr}");
}

/// Asserts a refusal as bad usage: exit status 2, an error line naming `needle`, no panic.
#[track_caller]
fn assert_usage_failure(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "panic on bad input: {stderr}");
    assert!(stderr.contains(needle), "error does not mention {needle:?}: {stderr}");
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// A tiny valid 2x2 RGB PNG.
fn tiny_png() -> Vec<u8> {
    let mut buf = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut buf, 2, 2);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&[255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255]).unwrap();
    }
    buf
}

const QUAD_OBJ: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl a\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";

#[test]
fn usage_errors_exit_with_status_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = scanatlas(&["no-such-command"], dir.path());
    assert_eq!(out.status.code(), Some(2));
    let out = scanatlas(&["stats"], dir.path());
    assert_eq!(out.status.code(), Some(2));
    // Unknown plugins and parameters: status 2 before the (missing) input is even read, with the
    // valid names listed.
    let out =
        scanatlas(&["defrag", "missing.obj", "-o", "o.obj", "--solver", "slim,rap"], dir.path());
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("arap, slim"));
    let cfg = write(dir.path(), "c.toml", b"[packer.horizon]\nsed = 1\n");
    let out = scanatlas(
        &["defrag", "missing.obj", "-o", "o.obj", "--config", cfg.to_str().unwrap()],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("seed, shuffle-below"));
    let out = scanatlas(&["plugins"], dir.path());
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("solver slim:") && text.contains("max-iterations = 25"), "{text}");
}

#[test]
fn stats_of_a_small_obj_prints_figures_and_json() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "m.mtl", b"newmtl a\nmap_Kd t.png\n");
    write(dir.path(), "t.png", &tiny_png());
    write(dir.path(), "q.obj", QUAD_OBJ.as_bytes());
    let out = scanatlas(&["stats", "q.obj", "--json"], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["faces"], 2);
    assert_eq!(v["charts_edge"], 1);
    assert_eq!(v["total_texels"], 4);
    // The unit square scaled to a 2x2 sheet: area 4 texels, border 8 texels.
    assert!((v["uv_area_texels"].as_f64().unwrap() - 4.0).abs() < 1e-9);
    assert!((v["uv_boundary_length_texels"].as_f64().unwrap() - 8.0).abs() < 1e-9);
    let out = scanatlas(&["stats", "q.obj"], dir.path());
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("charts"));
}

#[test]
fn bad_models_fail_cleanly_naming_file_and_place() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "m.mtl", b"newmtl a\nmap_Kd t.png\n");
    write(d, "t.png", &tiny_png());
    let cases: &[(&str, &[u8], &str)] = &[
        ("range.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "range.obj:4"),
        ("nan.obj", b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "nan.obj:2"),
        ("inf.obj", b"v 0 0 0\nv 1 inf 0\nv 0 1 0\nf 1 2 3\n", "inf.obj:2"),
        ("empty.obj", b"# nothing here\n", "empty.obj"),
        ("trunc.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\0\0\0\0", "trunc.ply"),
        ("huge.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n", "huge.ply"),
        ("bad.gltf", b"{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"byteLength\":12,\"uri\":\"data:application/octet-stream;base64,AAAAAAAAAAAAAAAA\"}],\"bufferViews\":[{\"buffer\":0,\"byteLength\":12}],\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":300,\"type\":\"VEC3\"}],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}]}", "bad.gltf"),
        ("trunc.glb", b"glTF\x02\0\0\0\xff\xff\0\0", "trunc.glb"),
        ("missing_tex.obj", b"mtllib nomtl.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "nomtl.mtl"),
    ];
    for (name, bytes, needle) in cases {
        write(d, name, bytes);
        let out = scanatlas(&["stats", name], d);
        assert_clean_failure(&out, needle);
    }
}

#[test]
fn bad_textures_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "q.obj", QUAD_OBJ.as_bytes());
    // Each case: the texture file the material points to, and what the error must name.
    let cases: &[(&str, Option<&[u8]>)] = &[
        ("gone.png", None),
        ("fake.png", Some(b"GIF89a\x01\0\x01\0")),
        ("trunc.png", Some(&b"\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR"[..])),
        ("zero.png", Some(&ZERO_PNG_HEADER[..])),
    ];
    for (tex, bytes) in cases {
        if let Some(b) = bytes {
            write(d, tex, b);
        }
        write(d, "m.mtl", format!("newmtl a\nmap_Kd {tex}\n").as_bytes());
        let out = scanatlas(&["stats", "q.obj"], d);
        assert_clean_failure(&out, tex);
    }
}

/// A PNG signature and IHDR chunk declaring a 0x0 image.
const ZERO_PNG_HEADER: [u8; 33] = [
    0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n', 0, 0, 0, 13, b'I', b'H', b'D', b'R', 0, 0,
    0, 0, 0, 0, 0, 0, 8, 2, 0, 0, 0, 0x2e, 0x7b, 0x43, 0x8a,
];

#[test]
fn convert_refuses_to_overwrite_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "m.mtl", b"newmtl a\nmap_Kd t.png\n");
    write(d, "t.png", &tiny_png());
    write(d, "q.obj", QUAD_OBJ.as_bytes());
    let out = scanatlas(&["convert", "q.obj", "-o", "q.obj"], d);
    assert_usage_failure(&out, "q.obj");
    assert_eq!(std::fs::read(d.join("q.obj")).unwrap(), QUAD_OBJ.as_bytes());
}

#[test]
fn demo_runs_without_input_and_synth_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = scanatlas(&["demo", "demo-out", "--quiet"], d);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("charts"), "{text}");
    assert!(d.join("demo-out/scan.obj").exists());

    for run in ["a", "b"] {
        let out = scanatlas(
            &["synth", run, "--faces", "3000", "--sheet-size", "256", "--seed", "5", "-q"],
            d,
        );
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    for f in ["scan.obj", "scan.mtl", "sheet_0.png"] {
        assert_eq!(
            std::fs::read(d.join("a").join(f)).unwrap(),
            std::fs::read(d.join("b").join(f)).unwrap(),
            "{f}"
        );
    }
}

#[test]
fn convert_round_trips_through_every_format() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = scanatlas(&["synth", "s", "--faces", "2000", "--sheet-size", "256", "-q"], d);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let base = scanatlas(&["stats", "s/scan.obj", "--json"], d);
    assert!(base.status.success());
    let base: serde_json::Value = serde_json::from_slice(&base.stdout).unwrap();
    for (model, tex) in
        [("c/a.gltf", "png"), ("c/b.glb", "tiff"), ("c/c.ply", "exr"), ("c/d.obj", "png")]
    {
        let out =
            scanatlas(&["convert", "s/scan.obj", "-o", model, "--texture-format", tex, "-q"], d);
        assert!(out.status.success(), "{model}: {}", String::from_utf8_lossy(&out.stderr));
        let st = scanatlas(&["stats", model, "--json"], d);
        assert!(st.status.success(), "{model}: {}", String::from_utf8_lossy(&st.stderr));
        let v: serde_json::Value = serde_json::from_slice(&st.stdout).unwrap();
        for key in ["faces", "vertices_3d", "charts_edge", "total_texels", "texture_sheets"] {
            assert_eq!(v[key], base[key], "{model}: {key}");
        }
        let (a, b) =
            (v["atlas_solidity"].as_f64().unwrap(), base["atlas_solidity"].as_f64().unwrap());
        assert!((a - b).abs() <= 1e-5 * b, "{model}: solidity {a} vs {b}");
    }
}

/// Checks a defrag output against its input: same face count and positions in order, every UV
/// inside the unit square, sheets that exist with the sizes the report gives.
fn check_defrag_output(d: &Path, input: &str, output: &str, report: &str) {
    let a = scanatlas_core::io::read_model(&d.join(input)).unwrap();
    let b = scanatlas_core::io::read_model(&d.join(output)).unwrap();
    assert_eq!(a.faces.len(), b.faces.len(), "{output}");
    for (i, (fa, fb)) in a.faces.iter().zip(&b.faces).enumerate() {
        for k in 0..3 {
            // glTF stores f32 positions: compare at that precision.
            let f32s = |p: [f64; 3]| p.map(|x| x as f32);
            assert_eq!(
                f32s(a.positions[fa.v[k].idx()]),
                f32s(b.positions[fb.v[k].idx()]),
                "face {i}"
            );
        }
        let uv = fb.uv.expect("every synth face keeps its UVs");
        for t in uv {
            let p = b.uvs[t.idx()];
            assert!((0.0..=1.0).contains(&p[0]) && (0.0..=1.0).contains(&p[1]), "{p:?}");
        }
    }
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join(report)).unwrap()).unwrap();
    let sheets = r["sheets"].as_array().unwrap();
    assert!(!sheets.is_empty());
    let sizes = r["output_stats"]["texture_sizes"].as_array().unwrap();
    assert_eq!(sheets.len(), sizes.len());
    assert_eq!(r["pack"]["sheets"].as_u64().unwrap() as usize, sheets.len());
    assert_eq!(r["faces"].as_u64().unwrap() as usize, a.faces.len());
    for s in sheets {
        let p = PathBuf::from(s.as_str().unwrap());
        let p = if p.is_absolute() { p } else { d.join(p) };
        assert!(p.exists(), "{}", p.display());
    }
    let texels: u64 = r["pack"]["texels"].as_u64().unwrap();
    assert_eq!(r["output_stats"]["total_texels"].as_u64().unwrap(), texels);
}

#[test]
fn defrag_writes_obj_and_glb_that_load_back() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = scanatlas(&["synth", "s", "--faces", "3000", "--sheet-size", "512", "-q"], d);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for (model, report) in [("o/out.obj", "o/r.json"), ("g/out.glb", "g/r.json")] {
        let out = scanatlas(&["defrag", "s/scan.obj", "-o", model, "--report", report, "-q"], d);
        assert!(out.status.success(), "{model}: {}", String::from_utf8_lossy(&out.stderr));
        check_defrag_output(d, "s/scan.obj", model, report);
    }
    // glTF in, OBJ out with another packer and texture format.
    let out = scanatlas(
        &[
            "defrag",
            "g/out.glb",
            "-o",
            "x/out.obj",
            "--report",
            "x/r.json",
            "--packer",
            "skyline",
            "--texture-format",
            "jpg",
            "--max-sheet-size",
            "256",
            "-q",
        ],
        d,
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    check_defrag_output(d, "g/out.glb", "x/out.obj", "x/r.json");
    assert!(d.join("x/out_0.jpg").exists());
}

#[test]
fn defrag_refuses_to_overwrite_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = scanatlas(&["synth", "s", "--faces", "3000", "--sheet-size", "512", "-q"], d);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let before = std::fs::read(d.join("s/scan.obj")).unwrap();
    let out = scanatlas(&["defrag", "s/scan.obj", "-o", "s/scan.obj", "-q"], d);
    assert_usage_failure(&out, "is the input");
    let out = scanatlas(&["defrag", "s/scan.obj", "-o", "s/./scan.obj", "-q"], d);
    assert_usage_failure(&out, "is the input");
    // An output whose sheet `sheet_0.png` would be the input's texture is refused too.
    let tex = std::fs::read(d.join("s/sheet_0.png")).unwrap();
    let out = scanatlas(&["defrag", "s/scan.obj", "-o", "s/sheet.obj", "-q"], d);
    assert_usage_failure(&out, "sheet_0.png");
    assert_eq!(std::fs::read(d.join("s/sheet_0.png")).unwrap(), tex);
    assert_eq!(std::fs::read(d.join("s/scan.obj")).unwrap(), before);
}

#[test]
fn demo_defragments_its_scan() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = scanatlas(&["demo", "demo-out", "-q"], d);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    for key in ["charts", "solidity", "texels", "vertex replication", "grid-preserved"] {
        assert!(text.contains(key), "{key}: {text}");
    }
    assert!(d.join("demo-out/defragged.obj").exists());
    assert!(d.join("demo-out/defragged_0.png").exists());
}

/// The report without its timings, speeds and output paths (the only parts that may differ
/// between two runs into two folders).
fn report_without_times(path: &Path) -> serde_json::Value {
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(m) => {
                m.retain(|k, _| {
                    let timing =
                        k.ends_with("_ms") || k.starts_with("ms_") || k.ends_with("_per_s");
                    let path = matches!(k.as_str(), "output" | "sheets" | "name");
                    !timing && !path && !matches!(k.as_str(), "timings" | "times")
                });
                m.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    strip(&mut v);
    v
}

#[test]
fn defrag_output_is_the_same_for_every_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = scanatlas(&["synth", "s", "--faces", "6000", "--sheet-size", "512", "-q"], d);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The default (one queue, judged ahead on a second thread when there is one), `--serial`,
    // and small clusters, so that several rounds of parallel queues run.
    let setups: [(&str, &[&str]); 3] =
        [("queue", &[]), ("serial", &["--serial"]), ("clusters", &["--cluster-faces", "1000"])];
    for (name, flags) in setups {
        for n in ["1", "2", "4"] {
            let dir = format!("{name}{n}");
            let (model, report) = (format!("{dir}/out.obj"), format!("{dir}/r.json"));
            let args = ["--threads", n, "defrag", "s/scan.obj", "-o", &model, "--report", &report];
            let out = scanatlas(&[&args[..], flags, &["-q"]].concat(), d);
            assert!(out.status.success(), "{dir}: {}", String::from_utf8_lossy(&out.stderr));
        }
        let first = report_without_times(&d.join(format!("{name}1/r.json")));
        let rounds = first["merge"]["rounds"].as_array().map_or(0, |r| r.len());
        assert_eq!(rounds >= 2, name == "clusters", "{name}: {rounds} rounds");
        for n in ["2", "4"] {
            for f in ["out.obj", "out.mtl", "out_0.png"] {
                let a = std::fs::read(d.join(format!("{name}1")).join(f)).unwrap();
                let b = std::fs::read(d.join(format!("{name}{n}")).join(f)).unwrap();
                assert!(a == b, "{name}: {f} differs between --threads 1 and {n}");
            }
            assert_eq!(
                first,
                report_without_times(&d.join(format!("{name}{n}/r.json"))),
                "{name}: reports differ between --threads 1 and {n}"
            );
        }
    }
    // One queue gives the serial output whether or not a second thread judges ahead.
    for f in ["out.obj", "out_0.png"] {
        let a = std::fs::read(d.join("queue2").join(f)).unwrap();
        let b = std::fs::read(d.join("serial2").join(f)).unwrap();
        assert!(a == b, "{f} differs between the default and --serial");
    }
}

/// The second job end to end through the binary: a synthetic capture, `build` from its COLMAP
/// cameras, `rig-score` of the result, then `defrag` of the built model (an atlas of projective
/// charts is a valid input like any other); and a clean error for a wrong photo folder.
#[test]
fn build_from_a_rig_then_defrag_its_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rig = ["synth-rig", "r", "--faces", "1500", "--photos", "8", "--width", "240"];
    let out = scanatlas(&[&rig[..], &["--height", "180", "-q"]].concat(), d);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let build = |images: &str, model: &str, report: &str| {
        let args = ["build", "--mesh", "r/mesh.obj", "--cameras", "r/sparse", "--images", images];
        scanatlas(&[&args[..], &["-o", model, "--report", report, "-q"]].concat(), d)
    };
    let out = build("r/images", "b/out.obj", "b/r.json");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("b/r.json")).unwrap()).unwrap();
    let input = scanatlas_core::io::read_model(&d.join("r/mesh.obj")).unwrap();
    assert_eq!(r["faces"].as_u64().unwrap() as usize, input.faces.len());
    assert!(r["seam_placement"]["passes"].as_u64().unwrap() >= 1, "{}", r["seam_placement"]);
    let score = |model: &str| -> serde_json::Value {
        let out = scanatlas(&["rig-score", "--rig", "r", model, "--json"], d);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let built = score("b/out.obj");
    for key in ["faces_dropped", "uv_flipped_faces", "overlap_face_pairs"] {
        assert_eq!(built[key].as_u64(), Some(0), "{key}: {built}");
    }
    let out =
        scanatlas(&["defrag", "b/out.obj", "-o", "d/out.obj", "--report", "d/r.json", "-q"], d);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    check_defrag_output(d, "b/out.obj", "d/out.obj", "d/r.json");
    let defragged = score("d/out.obj");
    let (a, b) = (built["psnr_db"].as_f64().unwrap(), defragged["psnr_db"].as_f64().unwrap());
    eprintln!("PSNR against the true colour: built {a:.2} dB, defragmented {b:.2} dB");
    // The merged charts are resampled (bilinear) wherever they are not grid-preserved (a good
    // part of the area here), which blurs detail at the photos' pixel scale: some loss is due.
    assert!(b > a - 6.0, "defrag of the build lost colour: {a:.2} -> {b:.2} dB");
    for key in ["faces_dropped", "uv_flipped_faces", "overlap_face_pairs"] {
        assert_eq!(defragged[key].as_u64(), Some(0), "{key}: {defragged}");
    }
    let charts = |s: &serde_json::Value| s["charts"].as_u64().unwrap();
    assert!(charts(&defragged) < charts(&built), "{} -> {}", charts(&built), charts(&defragged));
    // A photo folder without the photos: one clean error naming the missing photo.
    std::fs::create_dir_all(d.join("empty")).unwrap();
    assert_clean_failure(&build("empty", "e/out.obj", "e/r.json"), "photo_000.png");
    assert!(!d.join("e/out.obj").exists());
}

#[test]
fn completions_print_a_script_for_every_shell() {
    let dir = tempfile::tempdir().unwrap();
    for (shell, needle) in [
        ("bash", "complete -F _scanatlas"),
        ("zsh", "#compdef scanatlas"),
        ("fish", "complete -c scanatlas"),
        ("elvish", "scanatlas"),
        ("powershell", "Register-ArgumentCompleter"),
    ] {
        let out = scanatlas(&["completions", shell], dir.path());
        assert!(out.status.success(), "{shell}: {}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8(out.stdout).unwrap();
        assert!(text.contains(needle), "{shell}: no {needle:?}");
        // Completions follow the clap definitions: defrag's flags are in the script.
        assert!(text.contains("matching-tolerance"), "{shell}: no defrag flag");
    }
    let out = scanatlas(&["completions", "tcsh"], dir.path());
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn man_pages_print_and_write() {
    let dir = tempfile::tempdir().unwrap();
    let out = scanatlas(&["man"], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let page = String::from_utf8(out.stdout).unwrap();
    assert!(page.starts_with(".ie") || page.contains(".TH scanatlas"), "{page}");
    assert!(page.contains("defrag"), "{page}");
    let out = scanatlas(&["man", "defrag"], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let page = String::from_utf8(out.stdout).unwrap();
    assert!(page.contains(".TH scanatlas-defrag"), "{page}");
    assert!(page.contains("matching\\-tolerance"), "{page}");
    let out = scanatlas(&["man", "defragg"], dir.path());
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("stats"));
    let out = scanatlas(&["man", "--out-dir", "pages"], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for name in ["scanatlas.1", "scanatlas-defrag.1", "scanatlas-completions.1", "scanatlas-man.1"]
    {
        let text = std::fs::read_to_string(dir.path().join("pages").join(name)).unwrap();
        assert!(text.contains(".TH"), "{name}");
    }
}

#[test]
fn defrag_help_is_grouped_with_examples() {
    let dir = tempfile::tempdir().unwrap();
    let out = scanatlas(&["defrag", "--help"], dir.path());
    assert!(out.status.success());
    let help = String::from_utf8(out.stdout).unwrap();
    let headings =
        ["Paper parameters:", "Plugins:", "Packing:", "Textures:", "Repairs:", "Experiments:"];
    for h in headings {
        assert!(help.contains(h), "no heading {h:?} in\n{help}");
    }
    // Each flag sits under its group: a section runs from its heading to the next line that starts
    // in the first column (the next heading or the examples), whatever blank lines the long help
    // puts between its entries.
    let section = |h: &str| {
        let start = help.find(&format!("\n{h}")).unwrap() + 1;
        let body = &help[start + h.len()..];
        let end = body
            .match_indices('\n')
            .map(|(i, _)| i + 1)
            .find(|&i| body[i..].starts_with(|c: char| !c.is_whitespace()))
            .unwrap_or(body.len());
        body[..end].to_string()
    };
    assert!(section("Paper parameters:").contains("--matching-tolerance"));
    assert!(section("Plugins:").contains("--solver"));
    assert!(section("Packing:").contains("--max-sheet-size"));
    assert!(section("Textures:").contains("--texture-format"));
    assert!(section("Repairs:").contains("--no-untangle"));
    assert!(section("Experiments:").contains("--cluster-faces"));
    let examples = help.lines().filter(|l| l.starts_with("  scanatlas defrag ")).count();
    assert_eq!(examples, 2, "two examples:\n{help}");
}

#[test]
fn webp_sheets_are_written_read_and_referenced_through_the_gltf_extension() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "m.mtl", b"newmtl a\nmap_Kd t.png\n");
    write(d, "t.png", &tiny_png());
    write(d, "q.obj", QUAD_OBJ.as_bytes());
    for (format, name) in [("webp", "l"), ("webp-lossy", "y")] {
        let out = scanatlas(
            &["convert", "q.obj", "-o", &format!("{name}/q.gltf"), "--texture-format", format],
            d,
        );
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let doc: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.join(name).join("q.gltf")).unwrap()).unwrap();
        assert_eq!(doc["extensionsRequired"], serde_json::json!(["EXT_texture_webp"]), "{doc}");
        let texture = &doc["textures"][0];
        assert!(texture.get("source").is_none(), "{texture}");
        let image = texture["extensions"]["EXT_texture_webp"]["source"].as_u64().unwrap();
        let uri = doc["images"][image as usize]["uri"].as_str().unwrap();
        let bytes = std::fs::read(d.join(name).join(uri)).unwrap();
        assert!(bytes.starts_with(b"RIFF") && &bytes[8..12] == b"WEBP");
        // The written model reads back, WebP sheet included.
        let out = scanatlas(&["stats", &format!("{name}/q.gltf"), "--json"], d);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let stats: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(stats["texture_sizes"][0]["width"], 2, "{stats}");
    }
    // The lossless sheet holds the PNG's pixels exactly: converting back gives the same PNG data.
    let out = scanatlas(&["convert", "l/q.gltf", "-o", "p/q.obj", "--texture-format", "png"], d);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// `scanatlas stats --json | head -0`: a reader that stops reading ends the output quietly, as
/// with any Unix filter, instead of a panic on the broken pipe.
#[test]
fn a_closed_stdout_pipe_is_not_a_panic() {
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = scanatlas(&["synth", "s", "--faces", "2000", "--sheet-size", "256", "-q"], d);
    assert!(out.status.success());
    for args in [&["stats", "s/scan.obj", "--json"][..], &["stats", "s/scan.obj"], &["plugins"]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_scanatlas"))
            .args(args)
            .current_dir(d)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Closed before the command has written anything.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(out.status.success(), "{args:?}: {:?} {err}", out.status);
    }
}

/// A sheet wider than WebP allows is refused by `convert` before any work, not by the encoder
/// after the other sheets are written.
#[test]
fn convert_refuses_a_sheet_too_wide_for_webp_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut png = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png, 16384, 1);
        enc.set_color(png::ColorType::Rgb);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&vec![128; 16384 * 3]).unwrap();
    }
    write(d, "wide.png", &png);
    write(d, "m.mtl", b"newmtl a\nmap_Kd wide.png\n");
    write(d, "m.obj", QUAD_OBJ.as_bytes());
    let out = scanatlas(&["convert", "m.obj", "-o", "o/m.obj", "--texture-format", "webp"], d);
    assert_usage_failure(&out, "at most 16383");
    assert!(!d.join("o").exists(), "a refused conversion made its output folder");
}

/// `SCANATLAS_LOG` picks log levels per crate; a value that is not a list of directives is
/// named in a warning, and the run goes on at the level of its flags.
#[test]
fn log_directives_filter_by_crate_and_a_bad_one_is_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert!(scanatlas(&["-q", "synth", "s", "--faces", "200"], d).status.success());
    let run = |directives: &str, out: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_scanatlas"))
            .args(["defrag", "s/scan.obj", "-o", out])
            .current_dir(d)
            .env("SCANATLAS_LOG", directives)
            .output()
            .unwrap()
    };
    let info = run("scanatlas_cli=info", "a/o.obj");
    assert!(info.status.success());
    assert!(String::from_utf8_lossy(&info.stderr).contains("INFO"));
    let quiet = run("scanatlas_core=info", "b/o.obj");
    assert!(!String::from_utf8_lossy(&quiet.stderr).contains("INFO"));
    let bad = run("scanatlas=frob", "c/o.obj");
    assert!(bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("SCANATLAS_LOG=\"scanatlas=frob\" is not a list of log directives"),
        "{err}"
    );
}

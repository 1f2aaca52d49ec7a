//! The reading side of unattended runs, end to end through the `scanatlas` binary: every reader
//! warning reaches stderr and the report, `--strict` fails on them, degraded inputs (no
//! `usemtl`, non-finite UVs, far-off UVs, non-regular texture files, references outside the
//! model's folder) are handled loudly, and `convert` never writes what its reader rejects.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common::scanatlas;

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[track_caller]
fn assert_ok(out: &Output) {
    assert_eq!(out.status.code(), Some(0), "stderr: {}", stderr(out));
}

/// Asserts exit status 1 with an error line mentioning `needle`, and no panic.
#[track_caller]
fn assert_fails_with(out: &Output, needle: &str) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(1), "stderr: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    assert!(err.contains("scanatlas: error:"), "stderr: {err}");
    assert!(err.contains(needle), "error does not mention {needle:?}: {err}");
}

/// A synthetic scan of `faces` faces with one 512² sheet in `dir/name`; returns its folder.
fn synth(dir: &Path, name: &str, faces: u32) -> PathBuf {
    let n = faces.to_string();
    let out = scanatlas(&["synth", name, "--faces", &n, "--sheet-size", "512", "-q"], dir);
    assert_ok(&out);
    dir.join(name)
}

/// Rewrites `path` line by line.
fn edit_lines(path: &Path, mut f: impl FnMut(&str) -> Option<String>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = String::new();
    for line in text.lines() {
        if let Some(l) = f(line) {
            out.push_str(&l);
            out.push('\n');
        }
    }
    std::fs::write(path, out).unwrap();
}

/// `stats --json` of a model.
fn stats(dir: &Path, model: &Path) -> serde_json::Value {
    let out = scanatlas(&["stats", "--json", "--no-overlaps", model.to_str().unwrap()], dir);
    assert_ok(&out);
    serde_json::from_slice(&out.stdout).unwrap()
}

fn warning_codes(report: &serde_json::Value) -> Vec<String> {
    report["warnings"]
        .as_array()
        .expect("a warnings array")
        .iter()
        .map(|w| w["code"].as_str().unwrap().to_string())
        .collect()
}

/// Case 3: an OBJ whose `usemtl` line is removed kept no UV in `defrag` (every face came out
/// untextured, exit 0). Its faces now get the only textured material, with a warning on stderr
/// and in the report, and `--strict` refuses the run before writing anything.
#[test]
fn removed_usemtl_keeps_every_uv_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let r = synth(dir.path(), "r", 1000);
    edit_lines(&r.join("scan.obj"), |l| (!l.starts_with("usemtl")).then(|| l.to_string()));

    let out = scanatlas(
        &["defrag", "r/scan.obj", "-o", "o/o.obj", "--report", "o/report.json", "-q"],
        dir.path(),
    );
    assert_ok(&out);
    let err = stderr(&out);
    assert!(err.contains("scanatlas: warning:") && err.contains("material-assumed"), "{err}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("o/report.json")).unwrap()).unwrap();
    assert_eq!(warning_codes(&report), ["material-assumed"]);
    assert_eq!(report["faces_unpacked"], 0);
    let s = stats(dir.path(), &dir.path().join("o/o.obj"));
    assert_eq!(s["faces_without_uv"], 0, "{s}");
    assert!(s["charts_edge"].as_u64().unwrap() > 0, "{s}");

    let strict = scanatlas(&["--strict", "defrag", "r/scan.obj", "-o", "s/o.obj"], dir.path());
    assert_fails_with(&strict, "--strict");
    assert!(stderr(&strict).contains("scanatlas: warning:"), "{}", stderr(&strict));
    assert!(!dir.path().join("s").exists(), "the refused run left its output folder");
}

/// A warning of the packing (here a chart larger than the fixed sheet size) is found late in the
/// run: `--strict` still fails before the output set is committed, and leaves neither files nor
/// the folders it created (`s/deep`), while a folder that existed before stays.
#[test]
fn strict_fails_on_a_packing_warning_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    synth(dir.path(), "r", 1000);
    let run = |out: &str, strict: bool| {
        let mut args = vec!["defrag", "r/scan.obj", "-o", out, "--sheet-size", "64", "-q"];
        if strict {
            args.insert(0, "--strict");
        }
        scanatlas(&args, dir.path())
    };
    let lenient = run("o/o.obj", false);
    assert_ok(&lenient);
    assert!(stderr(&lenient).contains("sheet-size-exceeded"), "{}", stderr(&lenient));
    assert!(dir.path().join("o/o.obj").exists());

    let strict = run("s/deep/o.obj", true);
    assert_fails_with(&strict, "--strict");
    assert!(stderr(&strict).contains("sheet-size-exceeded"), "{}", stderr(&strict));
    assert!(!dir.path().join("s").exists(), "the refused run left its output folder");

    std::fs::create_dir(dir.path().join("kept")).unwrap();
    assert_fails_with(&run("kept/o.obj", true), "--strict");
    let left: Vec<_> = std::fs::read_dir(dir.path().join("kept")).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}

/// Case 3, renamed material: `usemtl` names a material the MTL does not define.
#[test]
fn renamed_material_keeps_every_uv_with_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let r = synth(dir.path(), "r", 1000);
    edit_lines(&r.join("scan.obj"), |l| {
        Some(if l.starts_with("usemtl") { "usemtl renamed".to_string() } else { l.to_string() })
    });
    let out = scanatlas(&["defrag", "r/scan.obj", "-o", "o/o.obj", "-q"], dir.path());
    assert_ok(&out);
    let err = stderr(&out);
    assert!(err.contains("undefined-material") && err.contains("'renamed'"), "{err}");
    assert!(err.contains("material-assumed"), "{err}");
    let s = stats(dir.path(), &dir.path().join("o/o.obj"));
    assert_eq!(s["faces_without_uv"], 0, "{s}");
}

/// Case 3 without a material to assume: two textured materials and faces without `usemtl`.
/// Nothing is guessed, but the loss is announced, and `stats` prints it too.
#[test]
fn faces_without_a_texture_are_announced() {
    let dir = tempfile::tempdir().unwrap();
    let r = synth(dir.path(), "r", 1000);
    let mtl = std::fs::read_to_string(r.join("scan.mtl")).unwrap();
    let second = mtl.replace("newmtl ", "newmtl second_");
    std::fs::write(r.join("scan.mtl"), format!("{mtl}\n{second}")).unwrap();
    edit_lines(&r.join("scan.obj"), |l| (!l.starts_with("usemtl")).then(|| l.to_string()));
    let out = scanatlas(&["stats", "r/scan.obj", "--no-overlaps"], dir.path());
    assert_ok(&out);
    assert!(stderr(&out).contains("scanatlas: warning:"), "{}", stderr(&out));
    assert!(stderr(&out).contains("uvs-without-texture"), "{}", stderr(&out));
    let strict = scanatlas(&["--strict", "stats", "r/scan.obj", "--no-overlaps"], dir.path());
    assert_fails_with(&strict, "uvs-without-texture");
}

/// Case 10: NaN and infinite UVs were accepted silently (faces came out with zero-area UVs).
/// Such faces are now read without UVs, with a warning, and `--strict` refuses them.
#[test]
fn non_finite_uvs_are_announced() {
    let dir = tempfile::tempdir().unwrap();
    let r = synth(dir.path(), "r", 1000);
    let mut k = 0;
    edit_lines(&r.join("scan.obj"), |l| {
        if l.starts_with("vt ") {
            k += 1;
            match k {
                1 => return Some("vt nan 0.5".into()),
                2 => return Some("vt inf -inf".into()),
                _ => {}
            }
        }
        Some(l.to_string())
    });
    let out = scanatlas(
        &["defrag", "r/scan.obj", "-o", "o/o.obj", "--report", "o/r.json", "-q"],
        dir.path(),
    );
    assert_ok(&out);
    assert!(stderr(&out).contains("non-finite-uvs"), "{}", stderr(&out));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("o/r.json")).unwrap()).unwrap();
    assert!(warning_codes(&report).contains(&"non-finite-uvs".to_string()));
    let strict = scanatlas(&["--strict", "defrag", "r/scan.obj", "-o", "s/o.obj"], dir.path());
    assert_fails_with(&strict, "non-finite-uvs");
}

/// A valid model gives no warning at all, so `--strict` passes it.
#[test]
fn a_valid_scan_has_no_warning() {
    let dir = tempfile::tempdir().unwrap();
    synth(dir.path(), "r", 1000);
    let out = scanatlas(&["--strict", "defrag", "r/scan.obj", "-o", "o/o.obj", "-q"], dir.path());
    assert_ok(&out);
    assert!(!stderr(&out).contains("warning"), "{}", stderr(&out));
}

/// Runs `scanatlas args` in `cwd` and returns its output with its peak resident memory in
/// bytes (from `wait4`, for this child alone).
// The child is reaped by `wait4` (which `Child::wait` cannot do: it drops the resource usage).
#[allow(clippy::zombie_processes)]
fn scanatlas_peak_rss(args: &[&str], cwd: &Path) -> (Output, u64) {
    use std::io::Read;
    let mut child = Command::new(env!("CARGO_BIN_EXE_scanatlas"))
        .args(args)
        .current_dir(cwd)
        .env_remove("SCANATLAS_LOG")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let (mut so, mut se) = (child.stdout.take().unwrap(), child.stderr.take().unwrap());
    let err_reader = std::thread::spawn(move || {
        let mut v = Vec::new();
        se.read_to_end(&mut v).unwrap();
        v
    });
    let mut stdout = Vec::new();
    so.read_to_end(&mut stdout).unwrap();
    let stderr = err_reader.join().unwrap();
    let mut status = 0;
    // SAFETY: a zeroed rusage is a valid value for wait4 to fill.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: the child is ours, not yet waited for; both pointers are valid.
    let pid = unsafe { libc::wait4(child.id() as libc::pid_t, &mut status, 0, &mut usage) };
    assert_eq!(pid, child.id() as libc::pid_t);
    use std::os::unix::process::ExitStatusExt;
    let out = Output { status: std::process::ExitStatus::from_raw(status), stdout, stderr };
    (out, usage.ru_maxrss as u64 * 1024)
}

/// Case 9: one far-off UV (`vt 1000000 1000000`) in a 1,000-face model cost gigabytes (the face
/// grid was sized from the UV bounding box), and then the packer refused the far chart. Memory now
/// follows the content, and the faces that span more than any sheet are collapsed onto a sane
/// corner with a `stray-uvs` warning: the run completes with every face, and `--strict` refuses
/// it before writing anything.
#[test]
fn a_far_off_uv_costs_no_memory_and_is_collapsed_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let r = synth(dir.path(), "r", 1000);
    let mut first = true;
    edit_lines(&r.join("scan.obj"), |l| {
        if l.starts_with("vt ") && std::mem::take(&mut first) {
            return Some("vt 1000000 1000000".into());
        }
        Some(l.to_string())
    });
    let (out, peak) = scanatlas_peak_rss(
        &["defrag", "r/scan.obj", "-o", "o/o.obj", "--report", "o/r.json", "-q"],
        dir.path(),
    );
    assert_ok(&out);
    assert!(stderr(&out).contains("[stray-uvs]"), "{}", stderr(&out));
    assert!(peak < 200 << 20, "peak resident memory {} MB", peak >> 20);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("o/r.json")).unwrap()).unwrap();
    assert!(warning_codes(&report).contains(&"stray-uvs".to_string()));
    assert_eq!(report["faces_unpacked"], 0, "{}", report["faces_unpacked"]);
    let in_stats = stats(dir.path(), &r.join("scan.obj"));
    let out_stats = stats(dir.path(), &dir.path().join("o/o.obj"));
    assert_eq!(out_stats["faces"], in_stats["faces"]);
    assert_eq!(out_stats["faces_without_uv"], 0, "{out_stats}");
    assert_eq!(out_stats["faces_without_texture"], 0, "{out_stats}");
    let strict = scanatlas(&["--strict", "defrag", "r/scan.obj", "-o", "s/o.obj"], dir.path());
    assert_fails_with(&strict, "stray-uvs");
    assert!(!dir.path().join("s/o.obj").exists());
}

/// The image fuzzer's finding: a 554-byte OpenEXR texture whose tiles claim 256 × 2,949,376
/// pixels over a 64 × 64 image made the decoder allocate and zero hundreds of megabytes before
/// it found the data missing. It is refused from its header now, within a small memory.
#[test]
fn an_exr_texture_with_tiles_far_larger_than_the_image_costs_no_memory() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let found = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz-regressions/image/exr-tiles-far-larger-than-the-image");
    std::fs::copy(found, d.join("t.exr")).unwrap();
    std::fs::write(d.join("m.mtl"), "newmtl m\nmap_Kd t.exr\n").unwrap();
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n";
    std::fs::write(d.join("m.obj"), obj).unwrap();
    let (out, peak) = scanatlas_peak_rss(&["convert", "m.obj", "-o", "o/o.obj"], d);
    assert_fails_with(&out, "far larger than the 64×64 image");
    assert!(peak < 64 << 20, "peak resident memory {} MB", peak >> 20);
}

/// Runs `scanatlas args`, failing the test instead of hanging when it takes over 60 s.
fn scanatlas_within_a_minute(args: &[&str], cwd: &Path) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_scanatlas"))
        .args(args)
        .current_dir(cwd)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > std::time::Duration::from_secs(60) {
            child.kill().unwrap();
            panic!("scanatlas {args:?} hangs");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

/// Case 13: a FIFO as a texture hung `stats`, `/dev/zero` was "empty file". Non-regular files
/// are refused at once, naming what they are.
#[test]
fn non_regular_textures_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let r = synth(dir.path(), "r", 200);
    let sheet = r.join("sheet_0.png");
    std::fs::remove_file(&sheet).unwrap();
    let c = std::ffi::CString::new(sheet.to_str().unwrap()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let out = scanatlas_within_a_minute(&["stats", "r/scan.obj"], dir.path());
    assert_fails_with(&out, "not a regular file but a FIFO");
    let out = scanatlas_within_a_minute(&["defrag", "r/scan.obj", "-o", "o/o.obj"], dir.path());
    assert_fails_with(&out, "a FIFO");

    let mtl = std::fs::read_to_string(r.join("scan.mtl")).unwrap();
    for (target, what) in [("/dev/zero", "a device"), (".", "a directory")] {
        let edited: String = mtl
            .lines()
            .map(|l| {
                if l.starts_with("map_Kd") {
                    format!("map_Kd {target}\n")
                } else {
                    format!("{l}\n")
                }
            })
            .collect();
        std::fs::write(r.join("scan.mtl"), edited).unwrap();
        let out = scanatlas_within_a_minute(&["stats", "r/scan.obj"], dir.path());
        assert_fails_with(&out, what);
    }
    // The model itself, too.
    let out = scanatlas_within_a_minute(&["stats", "/dev/zero"], dir.path());
    assert_fails_with(&out, "a device");
}

/// A glTF of one primitive over the buffer file `b.bin`: three positions, then `indices`
/// (u16) when given, drawn in `mode`, with a node `matrix` when given.
fn gltf(dir: &Path, name: &str, mode: u32, indices: &[u16], matrix: Option<&str>) -> PathBuf {
    let mut bin = Vec::new();
    for p in [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    std::fs::write(dir.join("b.bin"), &bin).unwrap();
    let (idx_view, idx_acc, idx_ref) = if indices.is_empty() {
        (String::new(), String::new(), String::new())
    } else {
        (
            format!(r#",{{"buffer":0,"byteOffset":36,"byteLength":{}}}"#, 2 * indices.len()),
            format!(
                r#",{{"bufferView":1,"componentType":5123,"count":{},"type":"SCALAR"}}"#,
                indices.len()
            ),
            r#","indices":1"#.to_string(),
        )
    };
    let matrix = matrix.map(|m| format!(r#","matrix":{m}"#)).unwrap_or_default();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"mesh":0{matrix}}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"mode":{mode}{idx_ref}}}]}}],
"buffers":[{{"uri":"b.bin","byteLength":{}}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}}{idx_view}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}{idx_acc}]}}"#,
        bin.len()
    );
    let path = dir.join(name);
    std::fs::write(&path, json).unwrap();
    path
}

/// Case 14: `convert` wrote models its own reader rejects, and dropped a partial triangle in
/// silence. Now it refuses before writing anything, or warns.
#[test]
fn convert_never_writes_what_its_reader_rejects() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // POINTS only: no triangle to write.
    gltf(d, "points.gltf", 0, &[], None);
    let out = scanatlas(&["convert", "points.gltf", "-o", "p/p.obj"], d);
    assert_fails_with(&out, "no triangles");
    assert!(!d.join("p/p.obj").exists());
    // A node matrix that sends the positions to infinity.
    let huge = "[1e308,0,0,0, 0,1e308,0,0, 0,0,1e308,0, 1e308,1e308,1e308,1]";
    gltf(d, "huge.gltf", 4, &[], Some(huge));
    let out = scanatlas(&["convert", "huge.gltf", "-o", "h/h.obj"], d);
    assert_fails_with(&out, "finite");
    assert!(!d.join("h/h.obj").exists());
    // Four indices: one triangle and one left over, announced.
    gltf(d, "partial.gltf", 4, &[0, 1, 2, 0], None);
    let out = scanatlas(&["convert", "partial.gltf", "-o", "q/q.obj", "-q"], d);
    assert_ok(&out);
    assert!(stderr(&out).contains("partial-triangle"), "{}", stderr(&out));
    let out = scanatlas(&["--strict", "convert", "partial.gltf", "-o", "s/s.obj"], d);
    assert_fails_with(&out, "partial-triangle");
    assert!(!d.join("s/s.obj").exists());
}

/// Case 15: a 20-point star polygon was fan-triangulated into 18 faces of which 8 turned over
/// in UV. It is now ear-clipped in its plane: no face turns over.
#[test]
fn a_star_polygon_has_no_flipped_uv_face() {
    let dir = tempfile::tempdir().unwrap();
    let r = synth(dir.path(), "r", 200);
    let mut obj = String::from("mtllib scan.mtl\n");
    let mut face = String::from("f");
    for i in 0..20 {
        let a = std::f64::consts::PI * f64::from(i) / 10.0;
        let rad = if i % 2 == 0 { 0.45 } else { 0.2 };
        let (x, y) = (0.5 + rad * a.cos(), 0.5 + rad * a.sin());
        obj.push_str(&format!("v {x} {y} 0\nvt {x} {y}\n"));
        face.push_str(&format!(" {0}/{0}", i + 1));
    }
    let mtl = std::fs::read_to_string(r.join("scan.mtl")).unwrap();
    let name = mtl.lines().find_map(|l| l.strip_prefix("newmtl ")).unwrap().to_string();
    obj.push_str(&format!("usemtl {name}\n{face}\n"));
    std::fs::write(r.join("star.obj"), obj).unwrap();
    let s = stats(dir.path(), &r.join("star.obj"));
    assert_eq!(s["faces"], 18, "{s}");
    assert_eq!(s["uv_flipped_faces"], 0, "{s}");
}

/// Case 17: errors quoted the first bytes of any file a model pointed at (`map_Kd
/// /etc/passwd`). They no longer print file contents, and `--confine` refuses references
/// outside the model's folder.
#[test]
fn references_outside_the_folder_leak_nothing_and_can_be_refused() {
    let dir = tempfile::tempdir().unwrap();
    let r = synth(dir.path(), "r", 200);
    let secret = dir.path().join("secret.txt");
    std::fs::write(&secret, "root:x:0:0:secret-content\n").unwrap();
    let mtl = std::fs::read_to_string(r.join("scan.mtl")).unwrap();
    let edited: String = mtl
        .lines()
        .map(|l| {
            if l.starts_with("map_Kd") { "map_Kd ../secret.txt\n".into() } else { format!("{l}\n") }
        })
        .collect();
    std::fs::write(r.join("scan.mtl"), &edited).unwrap();
    let out = scanatlas(&["stats", "r/scan.obj"], dir.path());
    assert_fails_with(&out, "not a PNG, JPEG, TIFF, OpenEXR or WebP file");
    let err = stderr(&out);
    for leak in ["root", "secret-content", "72 6f 6f 74"] {
        assert!(!err.contains(leak), "the error leaks the file: {err}");
    }
    let out = scanatlas(&["--confine", "stats", "r/scan.obj"], dir.path());
    assert_fails_with(&out, "outside the folder");
    // A texture inside the folder is fine with --confine.
    std::fs::write(r.join("scan.mtl"), mtl).unwrap();
    assert_ok(&scanatlas(&["--confine", "stats", "r/scan.obj"], dir.path()));
    // So is a glTF buffer inside its folder, but not one outside.
    gltf(dir.path(), "tri.gltf", 4, &[], None);
    assert_ok(&scanatlas(&["--confine", "stats", "tri.gltf"], dir.path()));
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let json = std::fs::read_to_string(dir.path().join("tri.gltf")).unwrap();
    std::fs::write(dir.path().join("sub/tri.gltf"), json.replace("\"b.bin\"", "\"../b.bin\""))
        .unwrap();
    assert_ok(&scanatlas(&["stats", "sub/tri.gltf"], dir.path()));
    let out = scanatlas(&["--confine", "stats", "sub/tri.gltf"], dir.path());
    assert_fails_with(&out, "outside the folder");
}

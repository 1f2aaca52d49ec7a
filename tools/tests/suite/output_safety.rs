//! Fault tests of the writing side (issue 32): no input is ever overwritten, a refused run writes
//! nothing, huge options never panic, bad usage exits 2, one run at a time per output, and
//! signals, kills and a full disk leave the destination whole and no stray file anywhere.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::common::snapshot;

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_scanatlas"));
    c.env_remove("SCANATLAS_LOG");
    c
}

fn scanatlas(args: &[&str], cwd: &Path) -> Output {
    bin().args(args).current_dir(cwd).output().expect("the scanatlas binary runs")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Asserts exit status `code`, no panic, and an error naming `needle`.
#[track_caller]
fn assert_refused(out: &Output, code: i32, needle: &str) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(code), "stderr: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    assert!(err.contains(needle), "error does not mention {needle:?}: {err}");
}

/// A small synthetic scan in `dir/name` (model `scan.<format>`, sheet `sheet_0.png`).
fn synth(dir: &Path, name: &str, faces: &str, sheet: &str, format: &str) -> PathBuf {
    let out = scanatlas(
        &["synth", name, "--faces", faces, "--sheet-size", sheet, "--format", format, "-q"],
        dir,
    );
    assert!(out.status.success(), "{}", stderr(&out));
    dir.join(name)
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = match std::fs::read_dir(dir) {
        Ok(rd) => rd.flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect(),
        Err(_) => Vec::new(),
    };
    v.sort();
    v
}

#[test]
fn the_report_never_overwrites_an_input_or_an_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let r = synth(d, "r", "1000", "512", "obj");
    let g = synth(d, "g", "1000", "512", "gltf");
    let before = snapshot(d);
    let cases: [(&str, &str, &str); 8] = [
        ("r/scan.obj", "r/sheet_0.png", "input file"),
        ("r/scan.obj", "r/scan.mtl", "input file"),
        ("r/scan.obj", "r/scan.obj", "input file"),
        ("r/scan.obj", "out/o.obj", "output set"),
        ("r/scan.obj", "out/o.mtl", "output set"),
        ("r/scan.obj", "r", "is a folder"),
        ("g/scan.gltf", "g/scan.bin", "input file"),
        ("g/scan.gltf", "g/sheet_0.png", "input file"),
    ];
    for (input, report, needle) in cases {
        let out = scanatlas(&["defrag", input, "-o", "out/o.obj", "--report", report, "-q"], d);
        assert_refused(&out, 2, needle);
        assert_eq!(snapshot(d), before, "--report {report} changed a file");
        assert!(!d.join("out").exists(), "a refused run made its output folder");
    }
    // A report beside the output is fine and says how the run ended.
    let out = scanatlas(&["defrag", "r/scan.obj", "-o", "out/o.obj", "--report", "out/r.json"], d);
    assert!(out.status.success(), "{}", stderr(&out));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("out/r.json")).unwrap()).unwrap();
    assert_eq!(report["status"], "completed");
    assert_eq!(
        std::fs::read(r.join("scan.obj")).unwrap(),
        before_file(&before, Path::new("r/scan.obj"))
    );
    let _ = g;
}

fn before_file(snap: &[(PathBuf, Vec<u8>)], p: &Path) -> Vec<u8> {
    snap.iter().find(|(q, _)| q == p).map(|(_, b)| b.clone()).unwrap()
}

#[test]
fn an_output_mtl_named_like_the_input_mtl_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let r = synth(d, "r", "1000", "512", "obj");
    let obj = std::fs::read_to_string(r.join("scan.obj")).unwrap();
    std::fs::write(r.join("a.obj"), obj.replace("mtllib scan.mtl", "mtllib shared.mtl")).unwrap();
    std::fs::copy(r.join("scan.mtl"), r.join("shared.mtl")).unwrap();
    let before = snapshot(d);
    let out = scanatlas(&["defrag", "r/a.obj", "-o", "r/shared.obj", "-q"], d);
    assert_refused(&out, 2, "shared.mtl");
    assert_eq!(snapshot(d), before);
    let out = scanatlas(&["convert", "r/a.obj", "-o", "r/shared.gltf", "-q"], d);
    assert!(out.status.success(), "a glTF output has no MTL: {}", stderr(&out));
}

#[test]
fn refused_runs_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, "r", "1000", "512", "obj");
    let g = synth(d, "g", "1000", "512", "gltf");
    // Another glTF naming the same buffer: an output `scan.gltf` beside it would write the
    // input's `scan.bin`.
    std::fs::copy(g.join("scan.gltf"), g.join("other.gltf")).unwrap();
    std::fs::remove_file(g.join("scan.gltf")).unwrap();
    let before = snapshot(d);
    let runs: [(&[&str], i32, &str); 7] = [
        (&["defrag", "r/scan.obj", "-o", "out/o.xyz"], 2, "unknown output format"),
        (&["defrag", "r/scan.obj", "-o", "out/o.obj", "--padding", "100000"], 2, "padding"),
        (&["defrag", "r/scan.obj", "-o", "out/o.obj", "--padding", "300"], 2, "no room"),
        (&["defrag", "r/scan.obj", "-o", "out/o.obj", "--report", "r"], 2, "folder"),
        (&["convert", "r/scan.obj", "-o", "r/scan.obj"], 2, "is the input"),
        (&["convert", "g/other.gltf", "-o", "g/scan.gltf"], 2, "scan.bin"),
        (&["defrag", "r/scan.obj", "-o", "r/sheet.obj"], 2, "sheet_0.png"),
    ];
    for (args, code, needle) in runs {
        let out = scanatlas(args, d);
        assert_refused(&out, code, needle);
        assert_eq!(snapshot(d), before, "{args:?} changed a file");
        assert!(!d.join("out").exists(), "{args:?} made its output folder");
        assert_eq!(names(&d.join("r")), ["scan.mtl", "scan.obj", "sheet_0.png", "synth.json"]);
    }
}

#[test]
fn build_refuses_its_mesh_a_photo_and_a_bad_packer_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = scanatlas(&["synth-rig", "rig", "--faces", "500", "--photos", "4", "-q"], d);
    assert!(out.status.success(), "{}", stderr(&out));
    let (mesh, cams) = ("rig/mesh.obj".to_string(), "rig/sparse".to_string());
    let photo = names(&d.join("rig/images")).into_iter().next().unwrap();
    let photo = format!("rig/images/{photo}");
    let before = snapshot(d);
    let base = ["build", "--mesh", &mesh, "--cameras", &cams, "--images", "rig/images"];
    let with = |extra: &[&str]| {
        let mut v: Vec<&str> = base.to_vec();
        v.extend_from_slice(extra);
        scanatlas(&v, d)
    };
    assert_refused(&with(&["-o", &mesh]), 2, "is the input");
    assert_refused(&with(&["-o", "o/b.obj", "--report", &mesh]), 2, "input file");
    assert_refused(&with(&["-o", "o/b.obj", "--report", &photo]), 2, "photo folder");
    assert_refused(&with(&["-o", "o/b.obj", "--packer", "nosuch"]), 2, "nosuch");
    assert_eq!(snapshot(d), before);
}

#[test]
fn huge_options_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, "r", "1000", "512", "obj");
    for limit in ["1e19", "1e308"] {
        let out = scanatlas(&["defrag", "r/scan.obj", "-o", "t/o.obj", "--time-limit", limit], d);
        assert!(out.status.success(), "--time-limit {limit}: {}", stderr(&out));
        std::fs::write(d.join("c.toml"), format!("time-limit = {limit}\n")).unwrap();
        let out = scanatlas(&["defrag", "r/scan.obj", "-o", "t/o.obj", "--config", "c.toml"], d);
        assert!(out.status.success(), "time-limit = {limit}: {}", stderr(&out));
    }
    for size in ["1000000000", "100000000", "65537", "70000x512"] {
        let out =
            scanatlas(&["defrag", "r/scan.obj", "-o", "m/o.obj", "--max-sheet-size", size], d);
        assert_refused(&out, 2, "65536");
        std::fs::write(d.join("c.toml"), format!("max-sheet-size = \"{size}\"\n")).unwrap();
        let out = scanatlas(&["defrag", "r/scan.obj", "-o", "m/o.obj", "--config", "c.toml"], d);
        assert_refused(&out, 2, "65536");
    }
    assert!(!d.join("m").exists());
    for n in ["0", "1025", "100000", "4294967296"] {
        let t = Instant::now();
        let out = scanatlas(&["--threads", n, "defrag", "r/scan.obj", "-o", "m/o.obj"], d);
        assert_refused(&out, 2, "threads");
        assert!(t.elapsed() < Duration::from_secs(5), "--threads {n} took {:?}", t.elapsed());
    }
}

#[test]
fn bad_synth_parameters_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for args in [["--faces", "10"], ["--sheet-size", "1"], ["--cameras", "0"]] {
        let mut v = vec!["synth", "s"];
        v.extend_from_slice(&args);
        let out = scanatlas(&v, d);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(!d.join("s").exists(), "{args:?} made its folder");
    }
}

/// Starts a defrag of `input` into `output` in `cwd`, with a separate work folder.
fn spawn_defrag(cwd: &Path, input: &str, output: &str, extra: &[&str]) -> Child {
    let mut args = vec!["defrag", input, "-o", output, "-q"];
    args.extend_from_slice(extra);
    bin().args(&args).current_dir(cwd).stderr(Stdio::piped()).spawn().unwrap()
}

/// Waits until `path` exists (or the child has ended).
fn wait_for(path: &Path, child: &mut Child) {
    let t = Instant::now();
    while !path.exists() && child.try_wait().unwrap().is_none() {
        assert!(t.elapsed() < Duration::from_secs(60), "{} never appeared", path.display());
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn signal(child: &Child, sig: &str) {
    let status = Command::new("kill").args([sig, &child.id().to_string()]).status().unwrap();
    assert!(status.success(), "kill {sig} failed");
}

/// Whether `dir` holds nothing of `o.obj`, or a complete set that loads (`stats` reads the
/// model and every sheet header).
fn assert_nothing_or_complete(cwd: &Path, dir: &str) {
    let model = cwd.join(dir).join("o.obj");
    if !model.exists() {
        let left: Vec<String> =
            names(&cwd.join(dir)).into_iter().filter(|n| !n.starts_with(".o.obj.")).collect();
        assert!(left.is_empty(), "no model but files {left:?}");
        return;
    }
    let out = scanatlas(&["stats", &format!("{dir}/o.obj")], cwd);
    assert!(out.status.success(), "the set does not load: {}", stderr(&out));
}

/// When the signals land after the run has started: at once, then at growing delays.
const SIGNAL_DELAYS_MS: [u64; 5] = [0, 200, 500, 1000, 2000];

/// A folder with a 20,000-face scan (`r/`) long enough to interrupt, and an empty `work/`.
fn scan_with_a_work_folder() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    synth(dir.path(), "r", "20000", "1024", "obj");
    std::fs::create_dir(dir.path().join("work")).unwrap();
    dir
}

/// SIGTERM and SIGINT stop the run cleanly whatever moment they land: exit 143 or 130 (or 0 if
/// the run was done), the old set or the whole new one, an "interrupted" report, no stray file.
#[test]
fn signals_leave_a_whole_set_and_no_stray_file() {
    let dir = scan_with_a_work_folder();
    let d = dir.path();
    for (k, &ms) in SIGNAL_DELAYS_MS.iter().enumerate() {
        let out_dir = format!("t{k}");
        let report = format!("{out_dir}.json");
        let extra = ["--work-dir", "work", "--report", report.as_str()];
        let mut child = spawn_defrag(d, "r/scan.obj", &format!("{out_dir}/o.obj"), &extra);
        // The lock is taken after the signal handlers are installed: from then on a signal
        // must stop the run cleanly.
        wait_for(&d.join(&out_dir).join(".o.obj.lock"), &mut child);
        std::thread::sleep(Duration::from_millis(ms));
        let sig = if k % 2 == 0 { "-TERM" } else { "-INT" };
        signal(&child, sig);
        let status = child.wait().unwrap();
        eprintln!("{sig} {ms} ms after the lock: {status:?}");
        let expect = if k % 2 == 0 { 143 } else { 130 };
        match status.code() {
            Some(0) => {}
            Some(c) => {
                assert_eq!(c, expect, "exit status after {sig} at {ms} ms");
                if d.join(&report).exists() {
                    let r: serde_json::Value =
                        serde_json::from_slice(&std::fs::read(d.join(&report)).unwrap()).unwrap();
                    assert_eq!(r["status"], "interrupted");
                }
            }
            None => panic!("killed by the signal itself at {ms} ms: the handler was not installed"),
        }
        assert_nothing_or_complete(d, &out_dir);
        let stray: Vec<String> =
            names(&d.join(&out_dir)).into_iter().filter(|n| n.starts_with('.')).collect();
        assert!(stray.is_empty(), "stray files after {sig} at {ms} ms: {stray:?}");
        assert!(names(&d.join("work")).is_empty(), "tile files left in the work folder");
    }
}

/// A SIGKILL cannot be handled: whatever moment it lands, the output folder holds the old set or
/// the new one, no tile file stays, and the next run clears what the killed one left.
#[test]
fn kills_leave_a_whole_set_and_the_next_run_clears_the_rest() {
    let dir = scan_with_a_work_folder();
    let d = dir.path();
    for (k, &ms) in SIGNAL_DELAYS_MS.iter().enumerate() {
        let out_dir = format!("k{k}");
        let mut child =
            spawn_defrag(d, "r/scan.obj", &format!("{out_dir}/o.obj"), &["--work-dir", "work"]);
        std::thread::sleep(Duration::from_millis(ms));
        child.kill().unwrap();
        child.wait().unwrap();
        assert_nothing_or_complete(d, &out_dir);
        // A kill leaves no tile file (they have no name) ...
        assert!(names(&d.join("work")).is_empty(), "tile files left after SIGKILL at {ms} ms");
        // ... and at most the staging folder and the lock file, which the next run clears.
        let out = scanatlas(&["defrag", "r/scan.obj", "-o", &format!("{out_dir}/o.obj"), "-q"], d);
        assert!(out.status.success(), "{}", stderr(&out));
        let stray: Vec<String> =
            names(&d.join(&out_dir)).into_iter().filter(|n| n.starts_with('.')).collect();
        assert!(stray.is_empty(), "the next run left {stray:?}");
    }
}

#[test]
fn a_second_run_on_the_same_output_fails_at_once_naming_the_first() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, "r", "20000", "1024", "obj");
    let mut first = spawn_defrag(d, "r/scan.obj", "o/o.obj", &[]);
    wait_for(&d.join("o/.o.obj.lock"), &mut first);
    let out = scanatlas(&["defrag", "r/scan.obj", "-o", "o/o.obj", "-q"], d);
    let first_done = first.try_wait().unwrap();
    assert!(first_done.is_none(), "the first run ended before the second started; make it longer");
    assert_refused(&out, 1, &format!("in use by pid {}", first.id()));
    assert!(first.wait().unwrap().success());
    let out = scanatlas(&["stats", "o/o.obj"], d);
    assert!(out.status.success(), "{}", stderr(&out));
}

#[test]
fn a_full_work_disk_is_a_message_not_a_signal() {
    let root = Command::new("id").arg("-u").output().unwrap();
    assert_eq!(
        String::from_utf8_lossy(&root.stdout).trim(),
        "0",
        "this test mounts a 2 MB tmpfs as the work folder and must run as root (CI does)"
    );
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, "r", "1000", "2048", "obj");
    std::fs::create_dir(d.join("small")).unwrap();
    let mount = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=2m", "tmpfs"])
        .arg(d.join("small"))
        .status()
        .unwrap();
    assert!(mount.success(), "mount of a tmpfs failed");
    let out = scanatlas(&["defrag", "r/scan.obj", "-o", "o/o.obj", "--work-dir", "small"], d);
    let left = names(&d.join("small"));
    let _ = Command::new("umount").arg(d.join("small")).status();
    assert_refused(&out, 1, "no space left on");
    assert!(left.is_empty(), "files left in the full work folder: {left:?}");
    let stray: Vec<String> = names(&d.join("o"));
    assert!(stray.is_empty(), "files left in the output folder: {stray:?}");
}

/// Starts a build from the rig in `cwd/rig` into `output`, with a report.
fn spawn_build(cwd: &Path, output: &str, report: &str) -> Child {
    let args = ["build", "--mesh", "rig/mesh.obj", "--cameras", "rig/sparse", "--images"];
    bin()
        .args(args)
        .args(["rig/images", "-o", output, "--report", report, "-q"])
        .current_dir(cwd)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

#[test]
fn build_takes_the_lock_and_a_signal_leaves_no_stray_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = scanatlas(&["synth-rig", "rig", "--faces", "20000", "--photos", "8", "-q"], d);
    assert!(out.status.success(), "{}", stderr(&out));

    // A second build on the same output fails at once, naming the first.
    let mut first = spawn_build(d, "b/o.obj", "b.json");
    wait_for(&d.join("b/.o.obj.lock"), &mut first);
    let base = ["build", "--mesh", "rig/mesh.obj", "--cameras", "rig/sparse", "--images"];
    let second = scanatlas(&[&base[..], &["rig/images", "-o", "b/o.obj", "-q"]].concat(), d);
    assert!(first.try_wait().unwrap().is_none(), "the first build ended too soon; make it longer");
    assert_refused(&second, 1, &format!("in use by pid {}", first.id()));
    assert!(first.wait().unwrap().success());
    assert_nothing_or_complete(d, "b");
    let stray: Vec<String> =
        names(&d.join("b")).into_iter().filter(|n| n.starts_with('.')).collect();
    assert!(stray.is_empty(), "a whole build left {stray:?}");

    // SIGTERM once the lock is taken: exit 143, an "interrupted" report, and the output folder
    // holds nothing of the run (or, had it ended first, the whole set).
    let mut child = spawn_build(d, "t/o.obj", "t.json");
    wait_for(&d.join("t/.o.obj.lock"), &mut child);
    signal(&child, "-TERM");
    let status = child.wait().unwrap();
    if status.code() != Some(0) {
        assert_eq!(status.code(), Some(143), "exit status after SIGTERM");
        let r: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.join("t.json")).unwrap()).unwrap();
        assert_eq!(r["status"], "interrupted");
    }
    assert_nothing_or_complete(d, "t");
    let stray: Vec<String> =
        names(&d.join("t")).into_iter().filter(|n| n.starts_with('.')).collect();
    assert!(stray.is_empty(), "stray files after SIGTERM: {stray:?}");
}

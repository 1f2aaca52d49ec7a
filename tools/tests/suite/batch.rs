//! `scanatlas batch` end to end on small synthetic models: isolation of a broken model, the log,
//! resuming, sharding, locks, time-outs, manifests, a SIGTERM in the middle, and the summary.

use std::collections::BTreeMap;
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_scanatlas");

fn scanatlas(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().expect("scanatlas runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `count` small synthetic models under `root/m<i>/` and a broken OBJ under `root/broken/`.
fn models(root: &Path, count: u32) {
    for i in 0..count {
        let dir = root.join(format!("m{i}"));
        let seed = (i + 1).to_string();
        let out = scanatlas(&[
            "-q",
            "synth",
            s(&dir),
            "--faces",
            "1000",
            "--sheet-size",
            "128",
            "--seed",
            &seed,
        ]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    std::fs::create_dir_all(root.join("broken")).unwrap();
    std::fs::write(root.join("broken/broken.obj"), "v 0 0 0\nf 7 8 9\n").unwrap();
}

fn log_entries(out: &Path) -> Vec<Value> {
    let text = std::fs::read_to_string(out.join("batch.jsonl")).unwrap_or_default();
    text.lines().map(|l| serde_json::from_str(l).expect("whole JSON lines")).collect()
}

/// Status counts per model name over the log.
fn statuses(out: &Path) -> BTreeMap<String, Vec<String>> {
    let mut m: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for e in log_entries(out) {
        m.entry(e["name"].as_str().unwrap().into())
            .or_default()
            .push(e["status"].as_str().unwrap().into());
    }
    m
}

fn model_names(root: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(root)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name() != "broken")
        .map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            format!("{name}/scan")
        })
        .collect();
    names.sort();
    names
}

#[test]
fn a_broken_model_fails_alone_and_a_rerun_skips_the_finished_ones() {
    let tmp = tempfile::tempdir().unwrap();
    let (input, out) = (tmp.path().join("in"), tmp.path().join("out"));
    models(&input, 3);
    let first = scanatlas(&["batch", s(&input), "-o", s(&out), "--jobs", "2", "--padding", "2"]);
    assert_eq!(first.status.code(), Some(1), "{}", String::from_utf8_lossy(&first.stderr));
    let st = statuses(&out);
    assert_eq!(st["broken/broken"], ["failed"]);
    for name in model_names(&input) {
        assert_eq!(st[&name], ["ok"], "{name}");
        let dir = out.join(&name);
        assert!(dir.join("scan.obj").is_file());
        let report: Value =
            serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
        // The command line's defrag options reach every model.
        assert_eq!(report["pack_options"]["padding"], 2, "{name}");
    }
    let failed = log_entries(&out).into_iter().find(|e| e["status"] == "failed").unwrap();
    assert!(failed["error"].as_str().unwrap().contains("broken.obj"), "{failed}");
    let ok = log_entries(&out).into_iter().find(|e| e["status"] == "ok").unwrap();
    assert!(ok["peak_rss_bytes"].as_u64().unwrap() > 1 << 20);
    assert!(ok["figures"]["charts_in"].as_u64().unwrap() > 0);
    assert_eq!(ok["shard"], "0/1");

    let t0 = Instant::now();
    let second = scanatlas(&["batch", s(&input), "-o", s(&out), "--padding", "2"]);
    let rerun = t0.elapsed();
    assert_eq!(second.status.code(), Some(1));
    let st = statuses(&out);
    assert_eq!(st["broken/broken"], ["failed", "failed"]);
    for name in model_names(&input) {
        assert_eq!(st[&name], ["ok", "skipped"], "{name}");
    }
    assert!(rerun < Duration::from_secs(10), "rerun took {rerun:?}");

    // Other options redo the models; so does a changed input.
    let third = scanatlas(&["batch", s(&input), "-o", s(&out), "--padding", "3"]);
    assert_eq!(third.status.code(), Some(1));
    for name in model_names(&input) {
        assert_eq!(statuses(&out)[&name].last().unwrap(), "ok", "{name}");
    }

    // A global switch reaches every model's process (and, changing the options, redoes them).
    let strict = scanatlas(&["--strict", "batch", s(&input), "-o", s(&out), "--padding", "3"]);
    assert_eq!(strict.status.code(), Some(1));
    let args_of = |name: &str| std::fs::read_to_string(out.join(name).join("report.json")).unwrap();
    for name in model_names(&input) {
        assert_eq!(statuses(&out)[&name].last().unwrap(), "ok", "{name}");
        assert!(args_of(&name).contains("\"pack_options\""), "{name}");
    }

    let summary = scanatlas(&["batch-summary", s(&out), "--json"]);
    assert_eq!(summary.status.code(), Some(1), "a failed model makes the summary fail");
    let json: Value = serde_json::from_slice(&summary.stdout).unwrap();
    assert_eq!(json["totals"]["models"], 4);
    assert_eq!(json["totals"]["by_status"]["ok"], 3);
    assert_eq!(json["totals"]["by_status"]["failed"], 1);
}

#[test]
fn shards_split_the_models_and_a_locked_model_is_busy() {
    let tmp = tempfile::tempdir().unwrap();
    let (input, out) = (tmp.path().join("in"), tmp.path().join("out"));
    models(&input, 3);
    std::fs::remove_dir_all(input.join("broken")).unwrap();
    // Another run holds the lock of m1.
    let lock_dir = out.join("m1/scan");
    std::fs::create_dir_all(&lock_dir).unwrap();
    let lock = std::fs::File::create(lock_dir.join(".batch.lock")).unwrap();
    // SAFETY: flock on a descriptor the test owns.
    assert_eq!(unsafe { libc::flock(lock.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) }, 0);
    for shard in ["0/2", "1/2"] {
        let run = scanatlas(&["batch", s(&input), "-o", s(&out), "--shard", shard]);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    }
    let entries = log_entries(&out);
    let shard_of = |name: &str| -> Vec<String> {
        entries
            .iter()
            .filter(|e| e["name"] == name)
            .map(|e| e["shard"].as_str().unwrap().to_string())
            .collect()
    };
    // Sorted m0, m1, m2: positions 0 and 2 in shard 0, position 1 in shard 1.
    assert_eq!(shard_of("m0/scan"), ["0/2"]);
    assert_eq!(shard_of("m1/scan"), ["1/2"]);
    assert_eq!(shard_of("m2/scan"), ["0/2"]);
    assert_eq!(statuses(&out)["m1/scan"], ["busy"]);
    drop(lock);
    let run = scanatlas(&["batch", s(&input), "-o", s(&out), "--shard", "1/2"]);
    assert!(run.status.success());
    assert_eq!(statuses(&out)["m1/scan"], ["busy", "ok"]);
}

#[test]
fn bad_usage_exits_2_before_any_model_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let (input, out) = (tmp.path().join("in"), tmp.path().join("out"));
    models(&input, 1);
    let cases: Vec<Vec<&str>> = vec![
        vec!["--solver", "no-such-solver"],
        vec!["--no-such-option"],
        vec!["--shard", "2/2"],
        vec!["--jobs", "0"],
    ];
    for extra in cases {
        let mut args = vec!["batch", s(&input), "-o", s(&out)];
        args.extend(&extra);
        let run = scanatlas(&args);
        assert_eq!(
            run.status.code(),
            Some(2),
            "{extra:?}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        assert!(log_entries(&out).is_empty(), "{extra:?}");
    }
    let manifest = tmp.path().join("list.jsonl");
    let model = input.join("m0/scan.obj");
    std::fs::write(
        &manifest,
        format!("{{\"input\": {:?}, \"options\": {{\"alpha\": \"x\"}}}}\n", s(&model)),
    )
    .unwrap();
    let run = scanatlas(&["batch", s(&manifest), "-o", s(&out)]);
    assert_eq!(run.status.code(), Some(2), "{}", String::from_utf8_lossy(&run.stderr));
}

#[test]
fn a_manifest_sets_names_and_options_per_model_and_a_timeout_fails_one() {
    let tmp = tempfile::tempdir().unwrap();
    let (input, out) = (tmp.path().join("in"), tmp.path().join("out"));
    models(&input, 2);
    let manifest = tmp.path().join("batch.toml");
    std::fs::write(
        &manifest,
        "[[model]]\ninput = \"in/m0/scan.obj\"\noutput = \"first\"\noptions = { padding = 6 }\n\n\
         [[model]]\ninput = \"in/m1/scan.obj\"\noutput = \"second\"\n",
    )
    .unwrap();
    let run = scanatlas(&["batch", s(&manifest), "-o", s(&out), "--padding", "1"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let padding = |name: &str| -> Value {
        let r: Value =
            serde_json::from_slice(&std::fs::read(out.join(name).join("report.json")).unwrap())
                .unwrap();
        r["pack_options"]["padding"].clone()
    };
    assert_eq!(padding("first"), 6);
    assert_eq!(padding("second"), 1);

    let timed = tmp.path().join("timed");
    let run = scanatlas(&["batch", s(&manifest), "-o", s(&timed), "--model-timeout", "0.001"]);
    assert_eq!(run.status.code(), Some(1));
    for e in log_entries(&timed) {
        assert_eq!(e["status"], "failed");
        assert!(e["error"].as_str().unwrap().contains("model-timeout"), "{e}");
        // A stopped model leaves no record, so a rerun redoes it.
        assert!(!timed.join(e["name"].as_str().unwrap()).join(".batch-record.json").exists());
    }
}

#[test]
fn sigterm_stops_the_batch_and_a_rerun_carries_on() {
    let tmp = tempfile::tempdir().unwrap();
    let (input, out) = (tmp.path().join("in"), tmp.path().join("out"));
    models(&input, 4);
    std::fs::remove_dir_all(input.join("broken")).unwrap();
    let mut child = Command::new(BIN)
        .args(["-q", "batch", s(&input), "-o", s(&out), "--jobs", "1"])
        .spawn()
        .unwrap();
    // Wait until the second model has started, then stop the batch.
    let second_log: PathBuf = out.join("m1/scan/run.log");
    let t0 = Instant::now();
    while !second_log.exists() && t0.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(5));
    }
    // SAFETY: a signal to the child this test started.
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(143));
    let st = statuses(&out);
    assert_eq!(st["m0/scan"], ["ok"]);
    let m1 = &st["m1/scan"];
    assert!(m1 == &["interrupted"] || m1 == &["ok"], "{m1:?}");
    assert!(!st.contains_key("m3/scan"), "no model starts after the signal");

    let rerun = scanatlas(&["batch", s(&input), "-o", s(&out)]);
    assert!(rerun.status.success(), "{}", String::from_utf8_lossy(&rerun.stderr));
    let st = statuses(&out);
    assert_eq!(st["m0/scan"], ["ok", "skipped"]);
    for name in ["m1/scan", "m2/scan", "m3/scan"] {
        let runs = &st[name];
        assert_eq!(runs.iter().filter(|s| *s == "ok").count(), 1, "{name}: {runs:?}");
        assert!(!runs.contains(&"failed".to_string()), "{name}: {runs:?}");
    }
}

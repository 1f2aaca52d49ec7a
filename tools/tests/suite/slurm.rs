//! `scanatlas batch` on a real Slurm: a two-task job array (the repository's
//! `deploy/slurm/batch-array.sh`) over synthetic models with one broken model among them, then
//! the same array again, then the summary job that depends on it. `.ci/slurm.sh` starts a
//! single-node Slurm and runs this test with SCANATLAS_SLURM=1; without a reachable Slurm the
//! test fails and says why.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};
use std::time::Instant;

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_scanatlas");
const GOOD_MODELS: u32 = 5;

fn run(program: &str, args: &[&str]) -> Output {
    Command::new(program).args(args).output().unwrap_or_else(|e| {
        panic!("cannot run {program}: {e} (is Slurm installed? see .ci/slurm.sh)")
    })
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn statuses(out: &Path) -> BTreeMap<String, Vec<(String, String)>> {
    let text = std::fs::read_to_string(out.join("batch.jsonl")).unwrap_or_default();
    let mut m: BTreeMap<String, Vec<(String, String)>> = BTreeMap::new();
    for line in text.lines() {
        let e: Value = serde_json::from_str(line).expect("whole JSON lines");
        m.entry(e["name"].as_str().unwrap().into())
            .or_default()
            .push((e["status"].as_str().unwrap().into(), e["shard"].as_str().unwrap().into()));
    }
    m
}

/// Submits the repository's array script as `--array=0-1` and waits for it; returns the job id.
fn array(script: &Path, input: &Path, out: &Path, logs: &Path) -> (String, Output) {
    let export = format!(
        "ALL,SCANATLAS={BIN},SCANATLAS_INPUT={},SCANATLAS_OUT={},SCANATLAS_ARGS=--padding 2",
        s(input),
        s(out)
    );
    let output = format!("{}/array-%A_%a.out", s(logs));
    let submitted = run(
        "sbatch",
        &[
            "--parsable",
            "--wait",
            "--array=0-1",
            "--cpus-per-task=1",
            "--mem=0",
            &format!("--export={export}"),
            &format!("--output={output}"),
            s(script),
        ],
    );
    let id = String::from_utf8_lossy(&submitted.stdout)
        .trim()
        .split(';')
        .next()
        .unwrap_or("")
        .to_string();
    (id, submitted)
}

#[test]
#[ignore = "needs a running Slurm: run `bash .ci/slurm.sh`"]
fn a_job_array_processes_every_model_once_and_a_rerun_skips_them() {
    assert_eq!(
        std::env::var("SCANATLAS_SLURM").as_deref(),
        Ok("1"),
        "SCANATLAS_SLURM=1 is not set: start Slurm with `bash .ci/slurm.sh`, which runs this test"
    );
    let info = run("sinfo", &["-h", "-o", "%t"]);
    let state = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.status.success() && (state.contains("idle") || state.contains("mix")),
        "Slurm is not reachable or has no idle node: sinfo said {:?} {:?}",
        state.trim(),
        String::from_utf8_lossy(&info.stderr).trim()
    );
    let t0 = Instant::now();
    let tmp = tempfile::Builder::new().prefix("scanatlas-slurm-test").tempdir_in("/tmp").unwrap();
    let (input, out, logs) =
        (tmp.path().join("models"), tmp.path().join("out"), tmp.path().join("logs"));
    std::fs::create_dir_all(&logs).unwrap();
    for i in 0..GOOD_MODELS {
        let dir = input.join(format!("m{i}"));
        let seed = (i + 1).to_string();
        let out = run(
            BIN,
            &["-q", "synth", s(&dir), "--faces", "2000", "--sheet-size", "256", "--seed", &seed],
        );
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    std::fs::create_dir_all(input.join("broken")).unwrap();
    std::fs::write(input.join("broken/broken.obj"), "v 0 0 0\nf 4 5 6\n").unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/slurm/batch-array.sh");
    let task_logs = || -> String {
        let mut all = String::new();
        for e in std::fs::read_dir(&logs).unwrap().flatten() {
            all += &format!(
                "--- {}\n{}",
                e.path().display(),
                std::fs::read_to_string(e.path()).unwrap_or_default()
            );
        }
        all
    };

    let (first_id, first) = array(&script, &input, &out, &logs);
    // The task with the broken model exits 1, and `sbatch --wait` passes that on.
    assert_eq!(first.status.code(), Some(1), "sbatch: {:?}\n{}", first, task_logs());
    let st = statuses(&out);
    assert_eq!(st.len(), GOOD_MODELS as usize + 1, "{st:?}\n{}", task_logs());
    let mut shards_seen = std::collections::BTreeSet::new();
    for (name, runs) in &st {
        let want = if name == "broken/broken" { "failed" } else { "ok" };
        assert_eq!(runs.len(), 1, "{name} was processed {} times: {runs:?}", runs.len());
        assert_eq!(runs[0].0, want, "{name}: {runs:?}\n{}", task_logs());
        shards_seen.insert(runs[0].1.clone());
    }
    assert_eq!(
        shards_seen.into_iter().collect::<Vec<_>>(),
        ["0/2", "1/2"],
        "both tasks took a share"
    );

    let (_, second) = array(&script, &input, &out, &logs);
    assert_eq!(second.status.code(), Some(1), "{}", task_logs());
    for (name, runs) in statuses(&out) {
        let want = if name == "broken/broken" { "failed" } else { "skipped" };
        assert_eq!(runs.len(), 2, "{name}: {runs:?}");
        assert_eq!(runs[1].0, want, "{name}: {runs:?}");
        assert_eq!(runs[1].1, runs[0].1, "{name} stays in its shard: {runs:?}");
    }

    // The summary job of the recipe, after the first array (`afterany`: it ended with a failure).
    let summary_log = format!("{}/summary.out", s(&logs));
    let summary = run(
        "sbatch",
        &[
            "--wait",
            &format!("--dependency=afterany:{first_id}"),
            &format!("--export=ALL,SCANATLAS={BIN},SCANATLAS_OUT={}", s(&out)),
            &format!("--output={summary_log}"),
            s(&script.with_file_name("batch-summary.sh")),
        ],
    );
    // The summary exits 1 as a model failed; its table lists every model.
    assert_eq!(summary.status.code(), Some(1), "{summary:?}");
    let table = std::fs::read_to_string(&summary_log).unwrap();
    assert!(table.contains("broken/broken") && table.contains("m4/scan"), "{table}");
    assert!(table.contains("5 skipped"), "{table}");
    let json: Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json["totals"]["models"], GOOD_MODELS + 1);
    eprintln!("slurm test: {:.1} s", t0.elapsed().as_secs_f64());
}

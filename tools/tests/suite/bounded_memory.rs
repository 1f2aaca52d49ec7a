//! The bounded-memory invariant, end to end: `defrag` of a multi-sheet synthetic scan peaks at a
//! resident size well below its decoded pixels, because sheets live in memory-mapped tile files
//! and are read a band at a time, never whole; and its report says how much disk those tile
//! files took.

use std::path::Path;
use std::process::Command;

/// The input: eight 4096² RGB sheets, 8 bits a channel.
const SHEETS: u64 = 8;
const SIDE: u64 = 4096;
const DECODED_BYTES: u64 = SHEETS * SIDE * SIDE * 3;

fn scanatlas(args: &[&str]) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_scanatlas"));
    cmd.args(args).env_remove("SCANATLAS_LOG");
    cmd
}

/// Runs `cmd` to its end and returns its peak resident set in bytes, read from the kernel's
/// accounting of that one child (`wait4`), so neither this test nor other children count.
// The child is reaped by `wait4`, which std's `Child::wait` cannot report the usage of.
#[allow(clippy::zombie_processes)]
fn peak_rss(cmd: &mut Command) -> u64 {
    let child = cmd.spawn().expect("the scanatlas binary runs");
    let pid = child.id() as libc::pid_t;
    let mut status: libc::c_int = 0;
    // SAFETY: `rusage` is plain old data that `wait4` fills; `pid` is our own unreaped child.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(r, pid, "wait4 failed: {}", std::io::Error::last_os_error());
    assert!(libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0, "the run failed: {status}");
    // `ru_maxrss` is in kilobytes on Linux.
    u64::try_from(usage.ru_maxrss).expect("a non-negative peak") * 1024
}

fn run_ok(cmd: &mut Command) {
    let out = cmd.output().expect("the scanatlas binary runs");
    assert!(out.status.success(), "stderr: {}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn defrag_of_a_multi_sheet_scan_stays_well_below_its_decoded_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("scan");
    let (sheets, side) = (SHEETS.to_string(), SIDE.to_string());
    let scan_s = scan.to_str().unwrap();
    run_ok(
        scanatlas(&["-q", "synth", scan_s, "--faces", "5000", "--sheets", &sheets])
            .args(["--sheet-size", &side]),
    );
    let out: &Path = &dir.path().join("out").join("out.obj");
    let input = scan.join("scan.obj");
    let report = dir.path().join("report.json");
    let peak = peak_rss(
        scanatlas(&["-q", "--threads", "2", "defrag"])
            .arg(&input)
            .arg("-o")
            .arg(out)
            .arg("--report")
            .arg(&report),
    );
    assert!(out.is_file(), "no output model");
    let written = std::fs::read_dir(out.parent().unwrap()).unwrap().count();
    assert!(written >= 3, "expected a multi-sheet output, found {written} files");
    // Half of the input's decoded pixels: a run that decoded even half of the sheets at once
    // would fail.
    let bound = DECODED_BYTES / 2;
    assert!(
        peak < bound,
        "peak resident set {} MB, bound {} MB (decoded input {} MB)",
        peak >> 20,
        bound >> 20,
        DECODED_BYTES >> 20
    );
    // The work folder held every input sheet's tile file at once (they are decoded ahead),
    // and beside them at most output sheets of about the same texels and their pyramids.
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&report).unwrap()).expect("a JSON report");
    let work = json["work_dir_peak_bytes"].as_u64().expect("work_dir_peak_bytes is a number");
    assert!(
        (DECODED_BYTES..4 * DECODED_BYTES).contains(&work),
        "work folder peak {} MB, decoded input {} MB",
        work >> 20,
        DECODED_BYTES >> 20
    );
}

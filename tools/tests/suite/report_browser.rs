//! The HTML report in a real browser: a synthetic scan is defragmented with `--report-dir`, the
//! page is rendered by headless Chromium, and the test checks that every picture loaded (the
//! page's own load check, read from the DOM) and that the screenshot is not blank.
//!
//! Needs Chromium, so it is ignored by a plain `cargo test`; `.ci/browser.sh` installs the Debian
//! package and runs it with `--ignored`, naming the browser in `SCANATLAS_CHROMIUM`. Without that
//! variable the test fails, never passes silently.

use std::path::{Path, PathBuf};
use std::process::Command;

fn scanatlas(args: &[&str], cwd: &Path) {
    let out = Command::new(env!("CARGO_BIN_EXE_scanatlas"))
        .args(args)
        .current_dir(cwd)
        .env_remove("SCANATLAS_LOG")
        .output()
        .expect("the scanatlas binary runs");
    assert!(out.status.success(), "scanatlas {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

fn chromium() -> PathBuf {
    let path = std::env::var_os("SCANATLAS_CHROMIUM").map(PathBuf::from).expect(
        "SCANATLAS_CHROMIUM must name the Chromium binary (.ci/browser.sh installs it and sets it)",
    );
    assert!(
        path.is_file(),
        "SCANATLAS_CHROMIUM={} is not a file: is chromium installed?",
        path.display()
    );
    path
}

/// Runs headless Chromium on `page` with `args` and returns its stdout.
fn headless(page: &Path, profile: &Path, args: &[&str]) -> String {
    let url = format!("file://{}", page.display());
    let out = Command::new(chromium())
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            "--hide-scrollbars",
            "--virtual-time-budget=10000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .arg(&url)
        .output()
        .expect("chromium runs");
    assert!(out.status.success(), "chromium failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Distinct colours of an RGB or RGBA PNG.
fn distinct_colours(png_path: &Path) -> usize {
    let decoder =
        png::Decoder::new(std::io::BufReader::new(std::fs::File::open(png_path).unwrap()));
    let mut reader = decoder.read_info().expect("a PNG screenshot");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("decodes");
    let bpp = info.color_type.samples();
    let mut seen = std::collections::HashSet::new();
    for px in buf[..info.buffer_size()].chunks_exact(bpp) {
        seen.insert([px[0], px[1], px[2]]);
    }
    seen.len()
}

#[test]
#[ignore = "needs Chromium: run .ci/browser.sh"]
fn report_renders_in_chromium_with_every_picture() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scanatlas(
        &["-q", "synth", "scan", "--faces", "4000", "--sheets", "2", "--sheet-size", "512"],
        d,
    );
    let model = std::fs::read_dir(d.join("scan"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "obj"))
        .expect("synth wrote an OBJ");
    let model = model.to_str().unwrap().to_string();
    scanatlas(&["-q", "defrag", &model, "-o", "out/out.obj", "--report-dir", "report"], d);
    let page = d.join("report/index.html");
    assert!(page.is_file() && d.join("report/report.json").is_file());
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(!html.contains("http://") && !html.contains("https://"), "the page must work offline");
    let n_img = html.matches("<img ").count();
    assert!(
        n_img >= 7,
        "two input sheets and one or more output sheets, and plots: {n_img} pictures"
    );

    let profile = tempfile::tempdir().unwrap();
    let dom = headless(&page, profile.path(), &["--dump-dom"]);
    let loaded = attr(&dom, "data-loaded").expect("the page's load check ran");
    let total = attr(&dom, "data-total").expect("the page's load check ran");
    assert_eq!(total, n_img.to_string(), "every <img> counted");
    assert_eq!(loaded, total, "pictures that did not load: {dom}");

    let shot = d.join("screenshot.png");
    headless(
        &page,
        profile.path(),
        &[&format!("--screenshot={}", shot.display()), "--window-size=1400,2400"],
    );
    let colours = distinct_colours(&shot);
    assert!(colours > 500, "the screenshot looks blank: {colours} distinct colours");
}

/// The value of the first `name="..."` attribute in `dom`.
fn attr(dom: &str, name: &str) -> Option<String> {
    let at = dom.find(&format!("{name}=\""))? + name.len() + 2;
    let end = dom[at..].find('"')?;
    Some(dom[at..at + end].to_string())
}

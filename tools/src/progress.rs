//! Progress on stderr. On a terminal (never with `--quiet`): a spinner or a bar with counts and
//! an ETA per long stage, replaced when the stage ends by a line with its time, so the stage times
//! stay on screen. With `--progress json`: one JSON line per stage start, update and end, whether
//! or not stderr is a terminal, for batch wrappers. Otherwise nothing, so cron logs stay clean.

use std::cell::Cell;
use std::io::IsTerminal;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// How progress is shown, chosen once by [`init`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Off,
    Bars,
    Json,
}

static MODE: OnceLock<Mode> = OnceLock::new();

/// JSON updates of a counted stage come at most this often (plus its last step).
const JSON_INTERVAL: Duration = Duration::from_millis(500);

/// Chooses how progress is shown for the whole run: JSON lines when asked, bars on a terminal
/// unless `quiet`, else nothing.
pub fn init(quiet: bool, json: bool) {
    let mode = if json {
        Mode::Json
    } else if !quiet && std::io::stderr().is_terminal() {
        Mode::Bars
    } else {
        Mode::Off
    };
    let _ = MODE.set(mode);
}

/// The mode [`init`] chose; a command called without it (tests) shows bars on a terminal unless
/// `quiet`.
fn mode(quiet: bool) -> Mode {
    match MODE.get() {
        Some(Mode::Json) => Mode::Json,
        Some(_) | None if quiet => Mode::Off,
        Some(&m) => m,
        None if std::io::stderr().is_terminal() => Mode::Bars,
        None => Mode::Off,
    }
}

/// One JSON progress line on stderr.
fn json_line(stage: &str, event: &str, extra: serde_json::Value) {
    let mut line = serde_json::json!({ "stage": stage, "event": event });
    if let (Some(obj), serde_json::Value::Object(more)) = (line.as_object_mut(), extra) {
        obj.extend(more);
    }
    eprintln!("{line}");
}

/// One long stage of a run.
pub struct Stage {
    name: String,
    mode: Mode,
    bar: Option<ProgressBar>,
    start: Instant,
    total: Option<u64>,
    done: Cell<u64>,
    last_json: Cell<Instant>,
}

impl Stage {
    fn new(name: &str, total: Option<u64>, quiet: bool) -> Self {
        let mode = mode(quiet);
        let now = Instant::now();
        if mode == Mode::Json {
            json_line(name, "start", serde_json::json!({ "total": total }));
        }
        Self {
            name: name.to_string(),
            mode,
            bar: None,
            start: now,
            total,
            done: Cell::new(0),
            last_json: Cell::new(now),
        }
    }

    /// A spinner for a stage of unknown length.
    pub fn spinner(msg: &str, quiet: bool) -> Self {
        let mut s = Self::new(msg, None, quiet);
        if s.mode == Mode::Bars {
            let bar = ProgressBar::new_spinner();
            bar.set_style(
                ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("valid template"),
            );
            bar.set_message(msg.to_string());
            bar.enable_steady_tick(Duration::from_millis(120));
            s.bar = Some(bar);
        }
        s
    }

    /// A bar for a stage of `len` steps, with the count and an ETA.
    pub fn bar(msg: &str, len: u64, quiet: bool) -> Self {
        let mut s = Self::new(msg, Some(len), quiet);
        if s.mode == Mode::Bars {
            let bar = ProgressBar::new(len);
            bar.set_style(
                ProgressStyle::with_template(
                    "{msg:24} [{bar:32}] {human_pos}/{human_len} {elapsed} (ETA {eta})",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            bar.set_message(msg.to_string());
            s.bar = Some(bar);
        }
        s
    }

    /// One more step done.
    pub fn inc(&self) {
        let done = self.done.get() + 1;
        self.done.set(done);
        if let Some(b) = &self.bar {
            b.inc(1);
        }
        if self.mode == Mode::Json {
            let now = Instant::now();
            let last = self.total.is_some_and(|t| done >= t);
            if last || now.duration_since(self.last_json.get()) >= JSON_INTERVAL {
                self.last_json.set(now);
                let elapsed = self.start.elapsed().as_secs_f64();
                let eta = self
                    .total
                    .filter(|_| done > 0)
                    .map(|t| elapsed / done as f64 * t.saturating_sub(done) as f64);
                let extra = serde_json::json!({
                    "done": done, "total": self.total, "elapsed_s": elapsed, "eta_s": eta
                });
                json_line(&self.name, "progress", extra);
            }
        }
    }

    /// Ends the stage: on a terminal its line stays, with the time it took.
    pub fn finish(self) {
        let secs = self.start.elapsed().as_secs_f64();
        match (self.mode, self.bar) {
            (Mode::Bars, Some(b)) => {
                b.set_style(ProgressStyle::with_template("  {msg}").expect("valid template"));
                b.finish_with_message(format!("{:<32} {:>7.1} s", self.name, secs));
            }
            (Mode::Json, _) => {
                json_line(&self.name, "done", serde_json::json!({ "seconds": secs }))
            }
            _ => {}
        }
    }
}

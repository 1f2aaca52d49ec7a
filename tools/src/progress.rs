//! Progress display on stderr: bars and spinners for long stages, shown only on a terminal and
//! never with `--quiet`, so cron logs stay clean.

use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

/// One long stage of a run.
pub struct Stage {
    bar: Option<ProgressBar>,
}

impl Stage {
    fn visible(quiet: bool) -> bool {
        !quiet && std::io::stderr().is_terminal()
    }

    /// A spinner for a stage of unknown length.
    pub fn spinner(msg: &str, quiet: bool) -> Self {
        if !Self::visible(quiet) {
            return Self { bar: None };
        }
        let bar = ProgressBar::new_spinner();
        bar.set_style(
            ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("valid template"),
        );
        bar.set_message(msg.to_string());
        bar.enable_steady_tick(Duration::from_millis(120));
        Self { bar: Some(bar) }
    }

    /// A bar for a stage of `len` steps.
    pub fn bar(msg: &str, len: u64, quiet: bool) -> Self {
        if !Self::visible(quiet) {
            return Self { bar: None };
        }
        let bar = ProgressBar::new(len);
        bar.set_style(
            ProgressStyle::with_template("{msg:24} [{bar:32}] {pos}/{len} {elapsed}")
                .expect("valid template")
                .progress_chars("=> "),
        );
        bar.set_message(msg.to_string());
        Self { bar: Some(bar) }
    }

    pub fn inc(&self) {
        if let Some(b) = &self.bar {
            b.inc(1);
        }
    }

    pub fn finish(self) {
        if let Some(b) = self.bar {
            b.finish_and_clear();
        }
    }
}

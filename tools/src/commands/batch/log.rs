//! `OUT_DIR/batch.jsonl`: one JSON object per model and attempt, appended as one `write` on a
//! file opened with `O_APPEND` and synced, so that shards writing to a shared folder interleave
//! whole lines and a line once written survives a crash.

use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

pub const LOG_FILE: &str = "batch.jsonl";

/// How an attempt ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    Ok,
    Failed,
    Skipped,
    Busy,
    Interrupted,
}

impl Status {
    pub fn label(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Failed => "failed",
            Status::Skipped => "skipped",
            Status::Busy => "busy",
            Status::Interrupted => "interrupted",
        }
    }
}

/// The key figures of a finished model, read from its report.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Figures {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub faces: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub charts_in: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub charts_out: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texels_in: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texels_out: Option<u64>,
    /// Share of the 3-D area whose texels are copied verbatim from the input grid (the input
    /// itself is on its grid everywhere).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grid_preserved_area_out: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uv_border_in: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uv_border_out: Option<f64>,
}

impl Figures {
    pub fn is_empty(&self) -> bool {
        *self == Figures::default()
    }
}

/// One line of the log.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Entry {
    /// The model's output name (its folder under OUT_DIR): the key of the summary.
    pub name: String,
    pub input: PathBuf,
    pub output: PathBuf,
    pub command: String,
    pub status: Status,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// UTC start of the attempt, RFC 3339.
    pub start: String,
    pub wall_s: f64,
    /// Peak resident memory of the model's process (`None` when no process ran).
    pub peak_rss_bytes: Option<u64>,
    pub threads: Option<usize>,
    pub warnings: Option<u64>,
    #[serde(default, skip_serializing_if = "Figures::is_empty")]
    pub figures: Figures,
    pub version: String,
    pub commit: String,
    pub host: String,
    pub shard: String,
    pub pid: u32,
}

/// Appends `entry` as one line: a single `write` of the whole line on an `O_APPEND` file, then,
/// with `sync`, `fdatasync`.
pub fn append(out_dir: &Path, entry: &Entry, sync: bool) -> Result<()> {
    let path = out_dir.join(LOG_FILE);
    let mut line = serde_json::to_vec(entry)?;
    line.push(b'\n');
    let mut file = OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .with_context(|| format!("opening the batch log {}", path.display()))?;
    file.write_all(&line).with_context(|| format!("writing the batch log {}", path.display()))?;
    if sync {
        file.sync_data().with_context(|| format!("syncing the batch log {}", path.display()))?;
    }
    Ok(())
}

/// Every entry of the log, in order; a line that does not parse (a torn write of a crashed
/// machine) is skipped with a warning.
pub fn read_all(out_dir: &Path) -> Result<Vec<Entry>> {
    let path = out_dir.join(LOG_FILE);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
    };
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        match serde_json::from_str(line) {
            Ok(e) => out.push(e),
            Err(e) => tracing::warn!("{}: line {} skipped: {e}", path.display(), i + 1),
        }
    }
    Ok(out)
}

/// This machine's host name.
pub fn host_name() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is valid for its whole length, which is passed.
    let rc = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    if rc != 0 {
        return "unknown".into();
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    String::from_utf8_lossy(&buf[..end]).into_owned()
}

/// `time` as RFC 3339 UTC with milliseconds (`2026-12-05T23:16:36.123Z`).
pub fn rfc3339(time: SystemTime) -> String {
    let since = time.duration_since(UNIX_EPOCH).unwrap_or_default();
    let secs = since.as_secs();
    let (days, rem) = (secs / 86_400, secs % 86_400);
    let (y, m, d) = civil_from_days(days as i64);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{:03}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60,
        since.subsec_millis()
    )
}

/// The proleptic Gregorian date of a day count since 1970-01-01 (Howard Hinnant's algorithm).
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn timestamps_are_rfc3339() {
        let t = UNIX_EPOCH + Duration::from_millis(1_796_512_596_123);
        assert_eq!(rfc3339(t), "2026-12-05T23:16:36.123Z");
        assert_eq!(
            rfc3339(UNIX_EPOCH + Duration::from_secs(951_782_400)),
            "2000-02-29T00:00:00.000Z"
        );
    }
}

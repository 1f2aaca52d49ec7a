//! `scanatlas batch-summary OUT_DIR`: one row per model from `batch.jsonl` (its latest outcome,
//! its latest run's time and memory, its figures) and the totals, as a text table or JSON.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Result;
use serde::Serialize;
use serde_json::Value;

use super::log::{self, Entry, Figures, Status};
use crate::cli::BatchSummaryArgs;

/// The key figures of a model from its `defrag` or `build` report.
pub fn figures_of_report(path: &Path) -> Figures {
    let Ok(bytes) = std::fs::read(path) else { return Figures::default() };
    let Ok(r) = serde_json::from_slice::<Value>(&bytes) else { return Figures::default() };
    let int = |p: &str| r.pointer(p).and_then(Value::as_u64);
    let float = |p: &str| r.pointer(p).and_then(Value::as_f64);
    if r.get("merge").is_some() {
        Figures {
            faces: int("/faces"),
            charts_in: int("/merge/charts_before"),
            charts_out: int("/merge/charts_after"),
            texels_in: int("/input_stats/total_texels"),
            texels_out: int("/output_stats/total_texels"),
            grid_preserved_area_out: float("/pack/preserved_area_fraction"),
            uv_border_in: float("/merge/uv_border_before"),
            uv_border_out: float("/merge/uv_border_after"),
        }
    } else {
        Figures {
            faces: int("/faces"),
            charts_out: int("/charts"),
            texels_out: int("/texels"),
            ..Figures::default()
        }
    }
}

/// One model's row.
#[derive(Debug, Serialize)]
pub struct Row {
    pub name: String,
    /// The latest outcome (`busy` only when nothing else was ever logged).
    pub status: Status,
    /// Attempts that ran a process (ok, failed, interrupted).
    pub runs: usize,
    pub wall_s: Option<f64>,
    pub peak_rss_bytes: Option<u64>,
    pub figures: Figures,
    pub error: Option<String>,
    pub host: String,
}

/// The totals over all rows.
#[derive(Debug, Default, Serialize)]
pub struct Totals {
    pub models: usize,
    pub by_status: BTreeMap<String, usize>,
    pub run_wall_s: f64,
    pub max_peak_rss_bytes: u64,
    pub charts_in: u64,
    pub charts_out: u64,
    pub texels_in: u64,
    pub texels_out: u64,
}

#[derive(Debug, Serialize)]
pub struct Summary {
    pub models: Vec<Row>,
    pub totals: Totals,
}

/// The summary of a log's entries.
pub fn summarize(entries: &[Entry]) -> Summary {
    let mut by_name: BTreeMap<&str, Vec<&Entry>> = BTreeMap::new();
    for e in entries {
        by_name.entry(e.name.as_str()).or_default().push(e);
    }
    let mut totals = Totals::default();
    let models: Vec<Row> = by_name
        .into_iter()
        .map(|(name, list)| {
            let ran =
                |e: &&&Entry| matches!(e.status, Status::Ok | Status::Failed | Status::Interrupted);
            let last = list
                .iter()
                .rev()
                .find(|e| e.status != Status::Busy)
                .unwrap_or(&list[list.len() - 1]);
            let last_run = list.iter().rev().find(ran);
            let figures = list
                .iter()
                .rev()
                .find(|e| !e.figures.is_empty())
                .filter(|_| matches!(last.status, Status::Ok | Status::Skipped))
                .map(|e| e.figures.clone())
                .unwrap_or_default();
            let row = Row {
                name: name.to_string(),
                status: last.status,
                runs: list.iter().filter(ran).count(),
                wall_s: last_run.map(|e| e.wall_s),
                peak_rss_bytes: last_run.and_then(|e| e.peak_rss_bytes),
                figures,
                error: last.error.clone(),
                host: last.host.clone(),
            };
            totals.models += 1;
            *totals.by_status.entry(row.status.label().into()).or_default() += 1;
            totals.run_wall_s += row.wall_s.unwrap_or(0.0);
            totals.max_peak_rss_bytes =
                totals.max_peak_rss_bytes.max(row.peak_rss_bytes.unwrap_or(0));
            totals.charts_in += row.figures.charts_in.unwrap_or(0);
            totals.charts_out += row.figures.charts_out.unwrap_or(0);
            totals.texels_in += row.figures.texels_in.unwrap_or(0);
            totals.texels_out += row.figures.texels_out.unwrap_or(0);
            row
        })
        .collect();
    Summary { models, totals }
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map_or("-".into(), |x| x.to_string())
}

/// The summary as an aligned text table with a totals line.
pub fn table(s: &Summary) -> String {
    let mut out = format!(
        "{:<32} {:<11} {:>4} {:>8} {:>8} {:>15} {:>9}  error\n",
        "model", "status", "runs", "wall s", "peak MiB", "charts in>out", "preserved"
    );
    for r in &s.models {
        let charts = match (r.figures.charts_in, r.figures.charts_out) {
            (None, None) => "-".to_string(),
            (a, b) => format!("{}>{}", opt(a), opt(b)),
        };
        out.push_str(&format!(
            "{:<32} {:<11} {:>4} {:>8} {:>8} {:>15} {:>9}  {}\n",
            r.name,
            r.status.label(),
            r.runs,
            opt(r.wall_s.map(|w| format!("{w:.1}"))),
            opt(r.peak_rss_bytes.map(|b| b >> 20)),
            charts,
            opt(r.figures.grid_preserved_area_out.map(|p| format!("{p:.3}"))),
            r.error.as_deref().unwrap_or("")
        ));
    }
    let t = &s.totals;
    let statuses: Vec<String> = t.by_status.iter().map(|(k, v)| format!("{v} {k}")).collect();
    out.push_str(&format!(
        "total: {} models ({}), run time {:.1} s, largest peak {} MiB, charts {} -> {}, texels {} -> {}\n",
        t.models,
        statuses.join(", "),
        t.run_wall_s,
        t.max_peak_rss_bytes >> 20,
        t.charts_in,
        t.charts_out,
        t.texels_in,
        t.texels_out
    ));
    out
}

/// Prints the summary of OUT_DIR; returns whether every model's latest outcome is a success.
pub fn print(out_dir: &Path, json: bool) -> Result<bool> {
    let s = summarize(&log::read_all(out_dir)?);
    if json {
        crate::commands::print_out(serde_json::to_string_pretty(&s)? + "\n")?;
    } else {
        crate::commands::print_out(table(&s))?;
    }
    Ok(s.models.iter().all(|r| matches!(r.status, Status::Ok | Status::Skipped)))
}

pub fn run(args: &BatchSummaryArgs) -> Result<()> {
    if !args.out_dir.join(log::LOG_FILE).is_file() {
        return Err(crate::commands::UsageError(format!(
            "{} has no {}: not a batch output folder",
            args.out_dir.display(),
            log::LOG_FILE
        ))
        .into());
    }
    if !print(&args.out_dir, args.json)? {
        anyhow::bail!("some models of {} failed or were interrupted", args.out_dir.display());
    }
    Ok(())
}

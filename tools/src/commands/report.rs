//! `scanatlas report INPUT OUTPUT -o DIR`, and the `--report-dir DIR` of `defrag` and `build`: the
//! offline HTML report of `scanatlas_core::report`, with its headline printed on stderr.

use std::path::Path;

use anyhow::{Context, Result};
use scanatlas_core::model::Model;
use scanatlas_core::pipeline::defrag::DefragReport;
use scanatlas_core::pipeline::load_model;
use scanatlas_core::report::plots::{BarChart, Series};
use scanatlas_core::report::{ReportInput, ReportOptions, ReportSummary, write_report};

use crate::cli::{ReportArgs, ReportPictureArgs};
use crate::progress::Stage;

fn options(p: &ReportPictureArgs) -> ReportOptions {
    ReportOptions {
        max_side: p.preview_size,
        colour_samples: p.colour_samples,
        ..ReportOptions::default()
    }
}

fn load(path: &Path) -> Result<Model> {
    load_model(path).with_context(|| format!("reading {}", path.display()))
}

/// Writes the report and says where it is, its headline and any warning.
fn write(dir: &Path, input: &ReportInput, pictures: &ReportPictureArgs, quiet: bool) -> Result<()> {
    let stage = Stage::spinner("writing the report", quiet);
    let summary = write_report(dir, input, &options(pictures))
        .with_context(|| format!("writing the report {}", dir.display()));
    stage.finish();
    let summary: ReportSummary = summary?;
    for w in &summary.warnings {
        tracing::warn!("report: {w}");
    }
    if !quiet {
        eprintln!("report {}: {}", dir.join("index.html").display(), summary.figures.headline);
    }
    Ok(())
}

pub fn run(args: &ReportArgs, quiet: bool) -> Result<()> {
    let stage = Stage::spinner("reading the models", quiet);
    let before = load(&args.input);
    let after = load(&args.output);
    stage.finish();
    let (before, after) = (before?, after?);
    let input = ReportInput {
        title: "scanatlas report",
        before: Some(&before),
        after: &after,
        before_stats: None,
        after_stats: None,
        extra_plots: &[],
        run: None,
    };
    write(&args.dir, &input, &args.pictures, quiet)
}

/// The report of a defrag run: its input against its output, with the run's figures.
pub fn after_defrag(
    dir: &Path,
    report: &DefragReport,
    pictures: &ReportPictureArgs,
    quiet: bool,
) -> Result<()> {
    let before = load(&report.input)?;
    let after = load(&report.output)?;
    let run = serde_json::to_value(report)?;
    let input = ReportInput {
        title: "scanatlas defrag",
        before: Some(&before),
        after: &after,
        before_stats: Some(&report.input_stats),
        after_stats: Some(&report.output_stats),
        extra_plots: &[],
        run: Some(&run),
    };
    write(dir, &input, pictures, quiet)
}

/// The report of a build run: the output alone (its mesh had no texture), with the seam colour
/// jump before and after the colour smoothing.
pub fn after_build(
    dir: &Path,
    output: &Path,
    run: &serde_json::Value,
    seam_jump: (f64, f64),
    pictures: &ReportPictureArgs,
    quiet: bool,
) -> Result<()> {
    let after = load(output)?;
    let chart = BarChart {
        title: "Colour jump across photo seams",
        x_desc: "",
        y_desc: "mean |difference| (8-bit)",
        bins: vec!["as projected".into(), "after smoothing".into()],
        series: vec![Series {
            name: "seam jump".into(),
            bars: vec![(seam_jump.0, [255, 130, 0]), (seam_jump.1, [30, 100, 255])],
        }],
        log_y: false,
    };
    let plots = [(
        chart.to_svg()?,
        "Mean colour difference just across the seams between charts from different photos; lower is better (seams less visible).".to_string(),
    )];
    let input = ReportInput {
        title: "scanatlas build",
        before: None,
        after: &after,
        before_stats: None,
        after_stats: None,
        extra_plots: &plots,
        run: Some(run),
    };
    write(dir, &input, pictures, quiet)
}

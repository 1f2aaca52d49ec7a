//! `scanatlas defrag INPUT -o OUTPUT`: the defragmentation pipeline with the plugins chosen by
//! name, a spinner per stage, a one-line summary on stderr and the full report as JSON on request.

use anyhow::{Context, Result};
use scanatlas_core::pipeline::PipelineError;
use scanatlas_core::pipeline::context::{RunPaths, check_paths};
use scanatlas_core::pipeline::defrag::{DefragConfig, DefragReport, defrag_with_progress};
use scanatlas_core::plugin::Registry;
use scanatlas_core::texture::ImageFormat;

use crate::cli::{DefragArgs, TextureFormatArg};
use crate::progress::Stage;

/// The image format a `--texture-format` value names.
pub fn image_format(f: TextureFormatArg) -> ImageFormat {
    match f {
        TextureFormatArg::Png => ImageFormat::Png,
        TextureFormatArg::Jpg => ImageFormat::Jpeg,
        TextureFormatArg::Tiff => ImageFormat::Tiff,
        TextureFormatArg::Exr => ImageFormat::Exr,
        TextureFormatArg::Webp | TextureFormatArg::WebpLossy => ImageFormat::Webp,
    }
}

/// The registry of every built-in plugin.
pub fn builtin_registry() -> Registry {
    let mut registry = Registry::default();
    scanatlas_plugins::register_builtin(&mut registry);
    registry
}

/// A pipeline error as the command line reports it: a refused option or path is bad usage
/// (exit status 2).
pub fn usage_or_failure(e: anyhow::Error) -> anyhow::Error {
    match e.downcast::<PipelineError>() {
        Ok(PipelineError::Usage(msg)) => super::UsageError(msg).into(),
        Ok(other) => other.into(),
        Err(e) => e,
    }
}

/// A run report with how the run ended (`completed`, or `interrupted` by a signal).
#[derive(serde::Serialize)]
struct StatusReport<'a, R: serde::Serialize> {
    status: &'a str,
    #[serde(flatten)]
    report: &'a R,
}

/// Writes a report's bytes, atomically, never over one of `protect`.
pub fn write_report(
    path: &std::path::Path,
    bytes: &[u8],
    protect: &[std::path::PathBuf],
) -> Result<()> {
    scanatlas_core::atomic::write_atomic(path, protect, |w| w.write_all(bytes))
        .with_context(|| format!("writing the report {}", path.display()))
}

/// Writes the report of a run with how it ended: the whole report with `"status": "completed"`,
/// or `about` with `"status": "interrupted"` when a signal stopped the run. A refused or failed
/// run writes none, since a refused path may be the report's own.
pub fn write_run_report<R: serde::Serialize>(
    path: &std::path::Path,
    result: &Result<R>,
    mut about: serde_json::Value,
    protect: &[std::path::PathBuf],
) -> Result<()> {
    let json = match result {
        Ok(report) => serde_json::to_vec_pretty(&StatusReport { status: "completed", report })?,
        Err(_) if scanatlas_core::cancel::requested() => {
            about["status"] = "interrupted".into();
            serde_json::to_vec_pretty(&about)?
        }
        Err(_) => return Ok(()),
    };
    write_report(path, &json, protect)
}

/// Runs the pipeline with one spinner per stage (none with `--quiet`).
pub fn run_pipeline(
    input: &std::path::Path,
    output: &std::path::Path,
    cfg: &DefragConfig,
    quiet: bool,
) -> Result<DefragReport> {
    let registry = builtin_registry();
    let mut stage: Option<Stage> = None;
    let report = defrag_with_progress(input, output, &registry, cfg, &mut |s| {
        if let Some(old) = stage.take() {
            old.finish();
        }
        tracing::info!("stage: {}", s.label());
        stage = Some(Stage::spinner(s.label(), quiet));
    });
    if let Some(old) = stage.take() {
        old.finish();
    }
    Ok(report?)
}

pub fn run(args: &DefragArgs, quiet: bool, strict: bool) -> Result<()> {
    // Every name and parameter is checked (exit status 2) before the model is read; the output
    // and report paths are checked by the pipeline before any work.
    let mut cfg = super::config::defrag_config(args, &builtin_registry())?;
    cfg.strict = strict;
    let paths = RunPaths {
        inputs: std::slice::from_ref(&args.input),
        output: &args.output,
        work_dir: args.work_dir.as_deref(),
        report: args.report.as_deref(),
    };
    check_paths(&paths).map_err(|e| super::UsageError(e.to_string()))?;
    let result = run_pipeline(&args.input, &args.output, &cfg, quiet).map_err(usage_or_failure);
    if let Some(path) = &args.report {
        let about = serde_json::json!({ "input": args.input, "output": args.output });
        write_run_report(path, &result, about, &[args.input.clone(), args.output.clone()])?;
    }
    let report = result?;
    tracing::info!("defrag finished in {:.1} s", report.times.total_ms / 1e3);
    super::report_warnings(&report.warnings, strict)?;
    print_summary(&report, quiet);
    if let Some(dir) = &args.report_dir {
        super::report::after_defrag(dir, &report, &args.report_pictures, quiet)?;
    }
    Ok(())
}

/// The end-of-run summary on stderr: the headline in plain words (sheet sizes, texel change,
/// charts, the surface copied texel for texel, defects, lost faces), then the merge and packing
/// figures for those who tune the run.
fn print_summary(report: &DefragReport, quiet: bool) {
    if quiet {
        return;
    }
    let headline = scanatlas_core::report::Figures::from_defrag(report).headline;
    eprintln!("wrote {}: {headline}", report.output.display());
    let m = &report.merge;
    eprintln!(
        "  merges {} accepted of {} attempted, distortion {:.4}, UV border {:.0} -> {:.0} texels, {:.1} s",
        m.accepted,
        m.attempted,
        m.energy_after,
        m.uv_border_before,
        m.uv_border_after,
        report.times.total_ms / 1e3
    );
    if let Some(p) = &report.pack {
        let out = &report.output_stats;
        eprintln!(
            "  packed {} charts with area and {} point faces ({} colour blocks) on {} sheets, occupancy {:.0}%, solidity {:.4} -> {:.4}",
            out.charts_edge_with_area,
            out.point_faces,
            p.palette.blocks,
            p.sheets,
            100.0 * p.occupancy,
            report.input_stats.atlas_solidity.unwrap_or(0.0),
            report.output_stats.atlas_solidity.unwrap_or(0.0)
        );
        if p.palette.speck_charts > 0 {
            eprintln!(
                "  {} specks (charts under {} texels² of UV area) became point faces: {} faces",
                p.palette.speck_charts,
                report.pack_options.map_or(0.0, |o| o.speck_area),
                p.palette.speck_faces
            );
        }
    }
    if report.work_dir_peak_bytes > 0 {
        eprintln!(
            "  work folder: temporary tile files took at most {}",
            scanatlas_core::output_set::human_bytes(report.work_dir_peak_bytes)
        );
    }
    if let Some(o) = report.pack_options.filter(|o| o.texel_scale != 1.0) {
        eprintln!(
            "  texel scale {}: every chart resampled, no texel copied verbatim",
            o.texel_scale
        );
    }
}

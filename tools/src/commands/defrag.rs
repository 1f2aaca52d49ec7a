//! `scanatlas defrag INPUT -o OUTPUT`: the defragmentation pipeline with the plugins chosen by
//! name, a spinner per stage, a one-line summary on stderr and the full report as JSON on request.

use anyhow::{Context, Result};
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
    }
}

/// The registry of every built-in plugin.
pub fn builtin_registry() -> Registry {
    let mut registry = Registry::default();
    scanatlas_plugins::register_builtin(&mut registry);
    registry
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
        stage = Some(Stage::spinner(s.label(), quiet));
    });
    if let Some(old) = stage.take() {
        old.finish();
    }
    Ok(report?)
}

pub fn run(args: &DefragArgs, quiet: bool) -> Result<()> {
    // Every name and parameter is checked (exit status 2) before the model is read.
    let cfg = super::config::defrag_config(args, &builtin_registry())?;
    let report = run_pipeline(&args.input, &args.output, &cfg, quiet)?;
    if let Some(path) = &args.report {
        let json = serde_json::to_vec_pretty(&report)?;
        scanatlas_core::atomic::write_atomic(path, std::slice::from_ref(&args.input), |w| {
            w.write_all(&json)
        })
        .with_context(|| format!("writing the report {}", path.display()))?;
    }
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
        eprintln!(
            "  packed {} charts on {} sheets, occupancy {:.0}%, solidity {:.4} -> {:.4}",
            p.charts,
            p.sheets,
            100.0 * p.occupancy,
            report.input_stats.atlas_solidity.unwrap_or(0.0),
            report.output_stats.atlas_solidity.unwrap_or(0.0)
        );
    }
}

//! `scanatlas defrag INPUT -o OUTPUT`: the defragmentation pipeline with the plugins chosen by
//! name, a spinner per stage, a one-line summary on stderr and the full report as JSON on request.

use anyhow::{Context, Result};
use scanatlas_core::defrag::MergeOptions;
use scanatlas_core::pack::PackOptions;
use scanatlas_core::pipeline::defrag::{DefragConfig, DefragReport, defrag_with_progress};
use scanatlas_core::plugin::{ParamValue, Params, Registry};
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

/// The pipeline configuration the arguments describe.
pub fn config(args: &DefragArgs) -> DefragConfig {
    let mut scorer_params = Params::new();
    scorer_params.insert("matching-tolerance".into(), ParamValue::Float(args.matching_tolerance));
    scorer_params.insert("boundary-tolerance".into(), ParamValue::Float(args.boundary_tolerance));
    DefragConfig {
        merge: MergeOptions {
            local_distortion: args.local_distortion,
            global_distortion: args.global_distortion,
            alpha: args.alpha,
            uv_border_target: args.uv_border_target,
            time_limit: args.time_limit,
            no_retry: args.no_retry,
            cluster_faces: if args.serial { 0 } else { args.cluster_faces },
            ..MergeOptions::default()
        },
        scorer: args.scorer.clone(),
        scorer_params,
        solver: args.solver.clone(),
        solver_params: Params::new(),
        packer: args.packer.clone(),
        packer_params: Params::new(),
        pack: PackOptions {
            padding: args.padding,
            max_sheet_size: args.max_sheet_size,
            ..PackOptions::default()
        },
        texture_format: args.texture_format.map(image_format),
        jpeg_quality: args.jpeg_quality,
        work_dir: args.work_dir.clone(),
        metrics_overlaps: None,
        merge_only: args.merge_only,
    }
}

/// Runs the pipeline with one spinner per stage (none with `--quiet`).
pub fn run_pipeline(
    input: &std::path::Path,
    output: &std::path::Path,
    cfg: &DefragConfig,
    quiet: bool,
) -> Result<DefragReport> {
    let mut registry = Registry::default();
    scanatlas_plugins::register_builtin(&mut registry);
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
    let cfg = config(args);
    let report = run_pipeline(&args.input, &args.output, &cfg, quiet)?;
    if let Some(path) = &args.report {
        let json = serde_json::to_vec_pretty(&report)?;
        scanatlas_core::atomic::write_atomic(path, std::slice::from_ref(&args.input), |w| {
            w.write_all(&json)
        })
        .with_context(|| format!("writing the report {}", path.display()))?;
    }
    if !quiet {
        let m = &report.merge;
        eprintln!(
            "wrote {}: charts {} -> {}, merges {} accepted of {} attempted, energy {:.4}, UV border {:.0} -> {:.0} texels, {:.1} s",
            args.output.display(),
            m.charts_before,
            m.charts_after,
            m.accepted,
            m.attempted,
            m.energy_after,
            m.uv_border_before,
            m.uv_border_after,
            report.times.total_ms / 1e3
        );
        if let Some(p) = &report.pack {
            eprintln!(
                "packed {} charts on {} sheets ({} texels, occupancy {:.3}), grid-preserved area {:.3}; solidity {:.4} -> {:.4}",
                p.charts,
                p.sheets,
                p.texels,
                p.occupancy,
                p.preserved_area_fraction,
                report.input_stats.atlas_solidity.unwrap_or(0.0),
                report.output_stats.atlas_solidity.unwrap_or(0.0)
            );
        }
    }
    Ok(())
}

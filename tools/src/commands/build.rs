//! `scanatlas build --mesh M --cameras PATH --images DIR -o OUTPUT`: a texture atlas from
//! registered photographs.

use anyhow::Result;
use scanatlas_core::photo_atlas::seam_placement::SeamPlacementOptions;
use scanatlas_core::pipeline::build::{BuildConfig, build_with_progress};
use scanatlas_core::pipeline::context::{RunPaths, check_paths};
use scanatlas_core::plugin::Registry;
use scanatlas_core::plugin::{Params, PluginKind};

use crate::cli::BuildArgs;
use crate::progress::Stage;

/// The build configuration the arguments ask for.
pub fn build_config(args: &BuildArgs) -> BuildConfig {
    BuildConfig {
        packer: args.packer.clone(),
        max_sheet_size: args.max_sheet_size,
        smoothing: !args.no_smoothing,
        frequency_split: !args.no_frequency_split,
        exposure: !args.no_exposure,
        resolution_weight: args.resolution_weight,
        seam_placement: !args.no_seam_placement,
        seam_placement_options: SeamPlacementOptions {
            camera_weight: args.seam_camera_weight,
            ..SeamPlacementOptions::default()
        },
        ..BuildConfig::default()
    }
}

pub fn run(args: &BuildArgs, quiet: bool, strict: bool) -> Result<()> {
    let mut registry = Registry::default();
    scanatlas_plugins::register_builtin(&mut registry);
    check_usage(args, &registry)?;
    let mut cfg = build_config(args);
    cfg.strict = strict;
    let mut stage: Option<Stage> = None;
    let (mesh, cameras, images) = (&args.mesh, &args.cameras, &args.images);
    let report =
        build_with_progress(mesh, cameras, images, &args.output, &registry, &cfg, &mut |s| {
            if let Some(old) = stage.take() {
                old.finish();
            }
            stage = Some(Stage::spinner(s.label(), quiet));
        });
    if let Some(old) = stage.take() {
        old.finish();
    }
    let result = report.map_err(|e| super::defrag::usage_or_failure(e.into()));
    if let Some(p) = &args.report {
        let about = serde_json::json!({ "mesh": mesh, "cameras": cameras, "output": args.output });
        let protect = [args.mesh.clone(), args.cameras.clone(), args.output.clone()];
        super::defrag::write_run_report(p, &result, about, &protect)?;
    }
    let report = result?;
    tracing::info!("build finished in {:.1} s", report.times.total_ms / 1e3);
    super::report_warnings(&report.warnings, strict)?;
    if let Some(dir) = &args.report_dir {
        let run = serde_json::to_value(&report)?;
        let jump = (report.seam_jump_before, report.seam_jump_after);
        super::report::after_build(dir, &args.output, &run, jump, &args.report_pictures, quiet)?;
    }
    if !quiet {
        if let Some(sp) = &report.seam_placement {
            eprintln!(
                "seam placement: {} faces moved in {} sweeps, seam edges {} -> {}, mean colour step across them {:.2} -> {:.2}",
                sp.faces_moved,
                sp.passes,
                sp.seam_edges_before,
                sp.seam_edges_after,
                sp.seam_step_before,
                sp.seam_step_after
            );
        }
        if let Some(fr) = &report.frequency {
            eprintln!(
                "frequency split: {} sub-charts from {} charts, faces per level {:?}, texels saved (padded rectangles) {}",
                fr.sub_charts, report.charts, fr.faces_per_level, fr.texels_saved
            );
        }
        eprintln!(
            "wrote {} ({} faces, {} unseen, {} charts, {} sheets, {} texels): packing {:.0}%, stretch {:.0}%, seam jump {:.2} -> {:.2}, {:.1} s",
            args.output.display(),
            report.faces,
            report.unseen_faces,
            report.charts,
            report.sheets.len(),
            report.texels,
            100.0 * report.packing_efficiency,
            100.0 * report.stretch_efficiency,
            report.seam_jump_before,
            report.seam_jump_after,
            report.times.total_ms / 1e3
        );
    }
    Ok(())
}

/// The checks of a build that need no work (exit status 2): the packer's name, and the output
/// and report paths against the mesh, the cameras and the photos.
fn check_usage(args: &BuildArgs, registry: &Registry) -> Result<()> {
    let usage = |msg: String| super::UsageError(msg);
    registry
        .check(PluginKind::Packer, &args.packer, &Params::new())
        .map_err(|e| usage(e.to_string()))?;
    let inputs = [args.mesh.clone(), args.cameras.clone()];
    let paths = RunPaths {
        inputs: &inputs,
        output: &args.output,
        work_dir: None,
        report: args.report.as_deref(),
    };
    check_paths(&paths).map_err(|e| usage(e.to_string()))?;
    // A photo is an input too: neither the model nor the report may land on one.
    let photos = args.images.canonicalize().ok();
    for path in std::iter::once(&args.output).chain(args.report.as_ref()) {
        let folder = scanatlas_core::io::paths::parent_dir(path).canonicalize().ok();
        if path.exists() && photos.is_some() && folder == photos {
            return Err(usage(format!(
                "{} is in the photo folder {}: choose another path",
                path.display(),
                args.images.display()
            ))
            .into());
        }
    }
    Ok(())
}

//! `scanatlas build --mesh M --cameras PATH --images DIR -o OUTPUT`: a texture atlas from
//! registered photographs.

use anyhow::{Context, Result};
use scanatlas_core::build::seam_placement::SeamPlacementOptions;
use scanatlas_core::pipeline::build::{BuildConfig, build};
use scanatlas_core::plugin::Registry;

use crate::cli::BuildArgs;
use crate::progress::Stage;

pub fn run(args: &BuildArgs, quiet: bool) -> Result<()> {
    let mut registry = Registry::default();
    scanatlas_plugins::register_builtin(&mut registry);
    let cfg = BuildConfig {
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
    };
    let stage = Stage::spinner("building the atlas", quiet);
    let report = build(&args.mesh, &args.cameras, &args.images, &args.output, &registry, &cfg)?;
    stage.finish();
    if let Some(p) = &args.report {
        let json = serde_json::to_string_pretty(&report)?;
        scanatlas_core::atomic::write_atomic::<std::io::Error, _>(p, &[], |w| {
            w.write_all(json.as_bytes())
        })
        .with_context(|| format!("writing {}", p.display()))?;
    }
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

//! `scanatlas defrag INPUT -o OUTPUT`: the defragmentation pipeline with the plugins chosen by
//! name, a one-line summary on stderr and the full report as JSON on request.

use anyhow::{Context, Result};
use scanatlas_core::defrag::MergeOptions;
use scanatlas_core::pipeline::defrag::{DefragConfig, defrag};
use scanatlas_core::plugin::{ParamValue, Params, Registry};

use crate::cli::DefragArgs;
use crate::progress::Stage;

pub fn run(args: &DefragArgs, quiet: bool) -> Result<()> {
    let mut registry = Registry::default();
    scanatlas_plugins::register_builtin(&mut registry);
    let mut scorer_params = Params::new();
    scorer_params.insert("matching-tolerance".into(), ParamValue::Float(args.matching_tolerance));
    scorer_params.insert("boundary-tolerance".into(), ParamValue::Float(args.boundary_tolerance));
    let cfg = DefragConfig {
        merge: MergeOptions {
            local_distortion: args.local_distortion,
            global_distortion: args.global_distortion,
            alpha: args.alpha,
            uv_border_target: args.uv_border_target,
            time_limit: args.time_limit,
            no_retry: args.no_retry,
            ..MergeOptions::default()
        },
        scorer: args.scorer.clone(),
        scorer_params,
        solver: args.solver.clone(),
        solver_params: Params::new(),
        merge_only: args.merge_only,
    };
    let stage = Stage::spinner("defragmenting", quiet);
    let report = defrag(&args.input, &args.output, &registry, &cfg)?;
    stage.finish();
    if let Some(path) = &args.report {
        let json = serde_json::to_vec_pretty(&report)?;
        scanatlas_core::atomic::write_atomic(path, &[args.input.clone()], |w| {
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
    }
    Ok(())
}

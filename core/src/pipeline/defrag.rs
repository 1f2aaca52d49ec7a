//! `defrag`: the texture defragmentation pipeline (load → prepare → merge → write), with the
//! plugins chosen by name from a [`Registry`] and a serializable run report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::PipelineError;
use crate::defrag::{MergeOptions, MergeReport, merge_charts, merged_model};
use crate::io::WriteOptions;
use crate::model::ImageSource;
use crate::plugin::{Params, Registry};
use crate::topology::{PreparationReport, Topology};

/// What to run and with which plugins.
#[derive(Clone, Debug)]
pub struct DefragConfig {
    pub merge: MergeOptions,
    pub scorer: String,
    pub scorer_params: Params,
    pub solver: String,
    pub solver_params: Params,
    /// Write the merged UVs on the input sheets, without packing or new textures (for measuring
    /// the merge stage alone).
    pub merge_only: bool,
}

impl Default for DefragConfig {
    fn default() -> Self {
        Self {
            merge: MergeOptions::default(),
            scorer: "paper".into(),
            scorer_params: Params::new(),
            solver: "arap".into(),
            solver_params: Params::new(),
            merge_only: false,
        }
    }
}

/// Milliseconds per pipeline stage.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct StageTimes {
    pub load_ms: f64,
    pub prepare_ms: f64,
    pub merge_ms: f64,
    pub write_ms: f64,
    pub total_ms: f64,
}

/// The run report (`--report FILE.json`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct DefragReport {
    pub input: PathBuf,
    pub output: PathBuf,
    pub scorer: String,
    pub solver: String,
    pub options: MergeOptions,
    pub faces: u64,
    pub preparation: PreparationReport,
    pub merge: MergeReport,
    pub times: StageTimes,
}

/// Runs the pipeline on `input`, writing `output`. Plugins are built (and their names and
/// parameters checked) before any model is read, so a bad name fails at once.
pub fn defrag(
    input: &Path,
    output: &Path,
    registry: &Registry,
    cfg: &DefragConfig,
) -> Result<DefragReport, PipelineError> {
    let t_all = Instant::now();
    cfg.merge.validate()?;
    let scorer = registry.scorer(&cfg.scorer, &cfg.scorer_params)?;
    let mut solver = registry.solver(&cfg.solver, &cfg.solver_params)?;
    if !cfg.merge_only {
        return Err(PipelineError::Usage(
            "packing and texture synthesis are not available yet: pass --merge-only".into(),
        ));
    }
    let mut times = StageTimes::default();

    let t = Instant::now();
    let model = super::load_model(input)?;
    times.load_ms = t.elapsed().as_secs_f64() * 1e3;

    let t = Instant::now();
    let mut topo = Topology::build(&model, &super::sheet_sizes(&model))?;
    times.prepare_ms = t.elapsed().as_secs_f64() * 1e3;

    let t = Instant::now();
    let (merge, _layout) = merge_charts(&mut topo, scorer.as_ref(), solver.as_mut(), &cfg.merge)?;
    times.merge_ms = t.elapsed().as_secs_f64() * 1e3;

    let t = Instant::now();
    let out_dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    super::create_dir(&out_dir)?;
    let mut protect = vec![input.to_path_buf()];
    protect.extend(model.sheets.iter().filter_map(|s| match &s.image {
        ImageSource::File(p) => Some(p.clone()),
        ImageSource::Embedded { .. } => None,
    }));
    let merged = merged_model(&model, &topo);
    crate::io::write_model(&merged, output, &WriteOptions { protect })?;
    times.write_ms = t.elapsed().as_secs_f64() * 1e3;
    times.total_ms = t_all.elapsed().as_secs_f64() * 1e3;
    Ok(DefragReport {
        input: input.to_path_buf(),
        output: output.to_path_buf(),
        scorer: cfg.scorer.clone(),
        solver: cfg.solver.clone(),
        options: cfg.merge.clone(),
        faces: model.faces.len() as u64,
        preparation: topo.report.clone(),
        merge,
        times,
    })
}

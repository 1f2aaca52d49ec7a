//! `scanatlas demo [OUT_DIR]`: the zero-input main command. Makes a small synthetic scan, runs the
//! main job on it and prints a short summary.

use std::path::PathBuf;

use anyhow::Result;
use scanatlas_core::metrics::{StatsOptions, atlas_stats};
use scanatlas_core::pipeline;
use scanatlas_core::synth::{Shape, SynthParams};

use crate::cli::{DemoArgs, ModelFormatArg};

pub fn run(args: &DemoArgs, quiet: bool) -> Result<()> {
    let out_dir = args.out_dir.clone().unwrap_or_else(|| PathBuf::from("scanatlas-demo"));
    let params = SynthParams {
        shape: Shape::Blob,
        faces: 20_000,
        cameras: 10,
        sheet_size: 1024,
        seed: 7,
        ..SynthParams::default()
    };
    let written = super::synth::write(&out_dir, &params, ModelFormatArg::Obj, quiet)?;
    let model = pipeline::load_model(&written.model)?;
    let stats =
        atlas_stats(&model, &pipeline::sheet_sizes(&model), &StatsOptions { overlaps: true });
    println!("scanatlas demo: a synthetic photogrammetry scan in {}", out_dir.display());
    print!("{}", super::stats::human(&written.model.display().to_string(), &stats));
    println!(
        "The atlas is shredded into {} charts with solidity {:.4}; `scanatlas defrag` is what repairs that.",
        stats.charts_edge,
        stats.atlas_solidity.unwrap_or(0.0)
    );
    Ok(())
}

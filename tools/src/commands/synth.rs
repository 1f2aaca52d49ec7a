//! `scanatlas synth OUT_DIR`: a synthetic photogrammetry-like scan with known true colour.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use scanatlas_core::io::{WriteOptions, write_model};
use scanatlas_core::synth::{self, Shape, SynthParams};
use scanatlas_core::texture::encode::{EncodeOptions, write_image};

use crate::cli::{ModelFormatArg, ShapeArg, SynthArgs};
use crate::progress::Stage;

/// Where a synthetic scan was written.
pub struct Written {
    pub model: PathBuf,
    pub report: synth::SynthReport,
}

pub fn run(args: &SynthArgs, quiet: bool) -> Result<()> {
    let params = SynthParams {
        shape: match args.shape {
            ShapeArg::Blob => Shape::Blob,
            ShapeArg::Terrain => Shape::Terrain,
            ShapeArg::Torus => Shape::Torus,
            ShapeArg::Multi => Shape::Multi,
        },
        faces: args.faces,
        cameras: args.cameras,
        sheet_size: args.sheet_size,
        seed: args.seed,
        sheets: args.sheets,
        specks: args.specks,
        ..SynthParams::default()
    };
    // Bad parameters are bad usage (exit status 2), found before anything is written.
    params.validate().map_err(|e| super::UsageError(e.to_string()))?;
    let t0 = std::time::Instant::now();
    let w = write(&args.out_dir, &params, args.format, quiet)?;
    if !quiet {
        eprintln!(
            "wrote {} ({} faces, {} charts, {} sheets) in {:.1} s",
            w.model.display(),
            w.report.faces,
            w.report.charts,
            w.report.sheets,
            t0.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// Generates and writes a synthetic scan into `out_dir`: the model, its sheets and `synth.json`.
pub fn write(
    out_dir: &Path,
    params: &SynthParams,
    format: ModelFormatArg,
    quiet: bool,
) -> Result<Written> {
    std::fs::create_dir_all(out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let stage = Stage::spinner("generating synthetic scan", quiet);
    let out = synth::generate(params, out_dir)?;
    stage.finish();

    let stage = Stage::bar("writing sheets", out.sheets.len() as u64, quiet);
    let mut model = out.model;
    for (k, store) in out.sheets.iter().enumerate() {
        let path = out_dir.join(synth::sheet_file_name(k));
        write_image(store, &path, &EncodeOptions::default())?;
        model.sheets[k].image = scanatlas_core::ImageSource::File(path);
        stage.inc();
    }
    stage.finish();

    let ext = match format {
        ModelFormatArg::Obj => "obj",
        ModelFormatArg::Gltf => "gltf",
        ModelFormatArg::Glb => "glb",
        ModelFormatArg::Ply => "ply",
    };
    let model_path = out_dir.join(format!("scan.{ext}"));
    write_model(&model, &model_path, &WriteOptions::default())?;
    let params_path = out_dir.join("synth.json");
    let json = serde_json::json!({ "params": params, "report": out.report });
    scanatlas_core::atomic::write_atomic::<std::io::Error, _>(&params_path, &[], |w| {
        serde_json::to_writer_pretty(&mut *w, &json)?;
        w.write_all(b"\n")
    })
    .with_context(|| format!("writing {}", params_path.display()))?;
    Ok(Written { model: model_path, report: out.report })
}

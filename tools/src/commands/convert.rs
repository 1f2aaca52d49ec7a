//! `scanatlas convert INPUT -o OUTPUT`: another model format, sheets re-encoded through tiles.

use anyhow::Result;
use scanatlas_core::pipeline::convert::{ConvertOptions, convert};

use crate::cli::{ConvertArgs, TextureFormatArg};
use crate::progress::Stage;

pub fn run(args: &ConvertArgs, quiet: bool, strict: bool) -> Result<()> {
    let opts = ConvertOptions {
        texture_format: args.texture_format.map(super::defrag::image_format),
        jpeg_quality: args.jpeg_quality,
        lossy_webp: args.texture_format.is_some_and(TextureFormatArg::is_lossy_webp),
        work_dir: args.work_dir.clone(),
        strict,
    };
    let stage = Stage::spinner("converting", quiet);
    let report = convert(&args.input, &args.output, &opts)
        .map_err(|e| super::defrag::usage_or_failure(e.into()))?;
    stage.finish();
    super::report_warnings(&report.warnings, strict)?;
    if !quiet {
        eprintln!(
            "wrote {} ({} faces, {} sheets): read {:.2} s, textures {:.2} s, write {:.2} s",
            args.output.display(),
            report.faces,
            report.sheets.len(),
            report.read_seconds,
            report.textures_seconds,
            report.write_seconds
        );
    }
    Ok(())
}

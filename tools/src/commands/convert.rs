//! `scanatlas convert INPUT -o OUTPUT`: another model format, sheets re-encoded through tiles.

use anyhow::Result;
use scanatlas_core::pipeline::convert::{ConvertOptions, convert};
use scanatlas_core::texture::ImageFormat;

use crate::cli::{ConvertArgs, TextureFormatArg};
use crate::progress::Stage;

pub fn run(args: &ConvertArgs, quiet: bool, strict: bool) -> Result<()> {
    let opts = ConvertOptions {
        texture_format: args.texture_format.map(|f| match f {
            TextureFormatArg::Png => ImageFormat::Png,
            TextureFormatArg::Jpg => ImageFormat::Jpeg,
            TextureFormatArg::Tiff => ImageFormat::Tiff,
            TextureFormatArg::Exr => ImageFormat::Exr,
        }),
        jpeg_quality: args.jpeg_quality,
        work_dir: args.work_dir.clone(),
        strict,
    };
    let stage = Stage::spinner("converting", quiet);
    let report = convert(&args.input, &args.output, &opts)?;
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

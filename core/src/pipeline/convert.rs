//! `convert`: a model to another format, its sheets decoded into tile stores and re-encoded one at
//! a time, so memory stays bounded by a sheet's page cache, not its decoded size.

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

use super::PipelineError;
use super::context::{RunContext, RunPaths, check_paths, tile_bytes};
use super::naming::SheetNaming;
use crate::model::{ImageSource, Model};
use crate::texture::encode::{EncodeOptions, write_image};
use crate::texture::{ImageFormat, TileStore, decode};
use crate::warnings::{Warning, check_strict};

/// Options of a conversion.
#[derive(Clone, Debug)]
pub struct ConvertOptions {
    /// Texture format of the output sheets; `None` keeps each sheet's input format.
    pub texture_format: Option<ImageFormat>,
    /// Quality (1 to 100) of JPEG sheets and of lossy WebP sheets.
    pub jpeg_quality: u8,
    /// WebP sheets are lossy (at `jpeg_quality`) instead of lossless.
    pub lossy_webp: bool,
    /// Folder for tile files; `None` = the output's folder.
    pub work_dir: Option<PathBuf>,
    /// Refuse to convert a model that has warnings (see `warnings`).
    pub strict: bool,
}

/// What a conversion did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ConvertReport {
    pub faces: usize,
    pub sheets: Vec<PathBuf>,
    pub read_seconds: f64,
    pub textures_seconds: f64,
    pub write_seconds: f64,
    /// What the reader found that degrades the model (see `warnings`).
    pub warnings: Vec<Warning>,
}

/// Refuses, before any work, a sheet larger than its output format can hold (WebP, JPEG).
fn check_format_sides(model: &Model, format: Option<ImageFormat>) -> Result<(), PipelineError> {
    for sheet in &model.sheets {
        let Some((w, h)) = sheet.size else { continue };
        let f = match format {
            Some(f) => f,
            None => ImageFormat::of_source(&sheet.image)?,
        };
        if let Some(limit) = f.max_side().filter(|&l| w.max(h) > l) {
            return Err(PipelineError::Usage(format!(
                "a {w}x{h} sheet does not fit {} (at most {limit} pixels a side): choose another \
                 --texture-format",
                f.extension().to_uppercase()
            )));
        }
    }
    Ok(())
}

/// Writes `sheets` where `naming` puts them for `output` in `enc`'s format, one encoder per
/// sheet side by side: each encoder is single-threaded, and a sheet's file depends on nothing
/// but its own texels, so the bytes are the same in any order. Returns the paths in sheet order.
pub(super) fn write_sheets(
    sheets: &[TileStore],
    output: &Path,
    naming: &SheetNaming,
    format: ImageFormat,
    enc: &EncodeOptions,
) -> Result<Vec<PathBuf>, PipelineError> {
    naming.create_folder(output)?;
    let paths = sheets
        .par_iter()
        .enumerate()
        .map(|(k, store)| {
            let path = naming.sheet_path(output, k, format);
            write_image(store, &path, enc).map(|()| path)
        })
        .collect::<Result<Vec<PathBuf>, _>>()?;
    Ok(paths)
}

/// Converts `input` to `output`; never overwrites the input or any file it refers to. The paths
/// are checked before the model is read, and the output set is committed as a whole (see
/// [`RunContext`]).
pub fn convert(
    input: &Path,
    output: &Path,
    opts: &ConvertOptions,
) -> Result<ConvertReport, PipelineError> {
    let inputs = [input.to_path_buf()];
    let paths =
        RunPaths { inputs: &inputs, output, work_dir: opts.work_dir.as_deref(), report: None };
    check_paths(&paths)?;
    let t0 = Instant::now();
    let mut model = super::load_model(input)?;
    let read_seconds = t0.elapsed().as_secs_f64();
    check_strict(opts.strict, &model.warnings)?;
    crate::io::check_output(&model, output)?;
    check_format_sides(&model, opts.texture_format)?;
    let ctx = RunContext::open(&paths, Some(&model))?;
    let tiles = model.sheets.iter().filter_map(|s| s.size).map(|(w, h)| tile_bytes(w, h, 4)).max();
    ctx.check_space(tiles.unwrap_or(0), input_bytes(ctx.protected()))?;

    let t1 = Instant::now();
    let staged = ctx.staged_output();
    ctx.sheet_naming().create_folder(&staged)?;
    let mut written = Vec::with_capacity(model.sheets.len());
    for (k, sheet) in model.sheets.iter_mut().enumerate() {
        ctx.checkpoint()?;
        let store = decode::decode_to_store(&sheet.image, ctx.work_dir())?;
        let format = match opts.texture_format {
            Some(f) => f,
            None => ImageFormat::of_source(&sheet.image)?,
        };
        let path = ctx.sheet_naming().sheet_path(&staged, k, format);
        let enc = EncodeOptions {
            format: Some(format),
            jpeg_quality: opts.jpeg_quality,
            webp_quality: opts.lossy_webp.then_some(opts.jpeg_quality),
            protect: ctx.protected().to_vec(),
        };
        write_image(&store, &path, &enc)?;
        sheet.image = ImageSource::File(path.clone());
        sheet.size = Some((store.width(), store.height()));
        written.push(ctx.final_path(&path));
    }
    let textures_seconds = t1.elapsed().as_secs_f64();

    let t2 = Instant::now();
    crate::io::write_model(&model, &staged, &ctx.write_options())?;
    ctx.commit()?;
    Ok(ConvertReport {
        faces: model.faces.len(),
        sheets: written,
        read_seconds,
        textures_seconds,
        write_seconds: t2.elapsed().as_secs_f64(),
        warnings: model.warnings,
    })
}

/// The total size of `files` (what a written set is expected to weigh, from its inputs).
pub(super) fn input_bytes(files: &[PathBuf]) -> u64 {
    files.iter().filter_map(|p| std::fs::metadata(p).ok()).map(|m| m.len()).sum()
}

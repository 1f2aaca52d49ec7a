//! Stage orchestration shared by the subcommands: loading a model with its sheet sizes, converting
//! between formats through the tile store, and the errors and reports of whole runs.

mod background;
pub mod build;
mod charts;
pub mod context;
pub mod convert;
mod decode_ahead;
pub mod defrag;
mod emit;
pub mod maps;
pub mod naming;
mod rigid_split;

use std::path::{Path, PathBuf};

use crate::io::IoError;
use crate::model::Model;
use crate::texture::TextureError;

/// Points `out` at the new atlas sheets (files beside the output model), one material per
/// sheet, named after the input's materials where they still fit (see [`naming`]).
pub(crate) fn set_atlas_sheets(out: &mut Model, paths: &[PathBuf], sizes: &[(u32, u32)]) {
    use crate::model::{ImageSource, Material, Sheet};
    out.map_sheets = Vec::new();
    out.sheets = paths
        .iter()
        .zip(sizes)
        .map(|(p, &size)| Sheet { image: ImageSource::File(p.clone()), size: Some(size) })
        .collect();
    let names = naming::material_names(&out.materials, out.sheets.len());
    out.materials = names
        .into_iter()
        .enumerate()
        .map(|(k, name)| Material {
            name,
            sheet: Some(crate::SheetId::from_usize(k)),
            ..Material::default()
        })
        .collect();
}

/// Errors of whole runs.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error(transparent)]
    Io(#[from] IoError),
    #[error(transparent)]
    Texture(#[from] TextureError),
    #[error("{path}: {source}")]
    File { path: PathBuf, source: std::io::Error },
    #[error("{0}")]
    Usage(String),
    #[error(transparent)]
    Plugin(#[from] crate::plugin::PluginError),
    #[error(transparent)]
    Topology(#[from] crate::topology::TopologyError),
    #[error(transparent)]
    Defrag(#[from] crate::defrag::DefragError),
    #[error("packing: {0}")]
    Pack(#[from] crate::pack::PackError),
    #[error(transparent)]
    Output(#[from] crate::output_set::OutputError),
    #[error(transparent)]
    Interrupted(#[from] crate::cancel::Interrupted),
    /// Cameras or photos of a `build` that cannot be read or do not fit together.
    #[error(transparent)]
    Build(#[from] crate::photo_atlas::BuildError),
    #[error(transparent)]
    Strict(#[from] crate::warnings::StrictError),
}

/// Reads a model and fills in every sheet's size from its image header (no pixels decoded).
/// A missing or unreadable texture is an error naming the file.
pub fn load_model(path: &Path) -> Result<Model, PipelineError> {
    let mut model = crate::io::read_model(path)?;
    probe_sheet_sizes(&mut model)?;
    Ok(model)
}

/// Fills `Sheet::size` of every sheet whose size is unknown.
pub fn probe_sheet_sizes(model: &mut Model) -> Result<(), TextureError> {
    for sheet in &mut model.sheets {
        if sheet.size.is_none() {
            sheet.size = Some(crate::texture::decode::probe_size(&sheet.image)?);
        }
    }
    Ok(())
}

/// The sizes of a model's sheets, in sheet order.
pub fn sheet_sizes(model: &Model) -> Vec<Option<(u32, u32)>> {
    model.sheets.iter().map(|s| s.size).collect()
}

/// Creates a folder (and its parents), naming it in the error.
pub fn create_dir(path: &Path) -> Result<(), PipelineError> {
    std::fs::create_dir_all(path)
        .map_err(|e| PipelineError::File { path: path.to_path_buf(), source: e })
}

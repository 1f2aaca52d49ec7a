//! glTF 2.0 (.gltf and .glb) reader and writer.

use std::path::Path;

use super::{IoError, WriteOptions};
use crate::model::Model;

/// The scene structure of a glTF file, kept so that writing back changes only UVs, base-colour
/// images and samplers.
#[derive(Clone, Debug, Default)]
pub struct GltfScene {}

/// Reads a .gltf or .glb file.
pub fn read(path: &Path) -> Result<Model, IoError> {
    Err(IoError::unsupported(path, "glTF reader not written yet"))
}

/// Writes `model` as .gltf (+ .bin) or, when `binary`, as one .glb.
pub fn write(
    _model: &Model,
    path: &Path,
    _opts: &WriteOptions,
    _binary: bool,
) -> Result<(), IoError> {
    Err(IoError::unsupported(path, "glTF writer not written yet"))
}

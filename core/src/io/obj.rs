//! Wavefront OBJ + MTL reader and writer.

use std::path::Path;

use super::{IoError, WriteOptions};
use crate::model::Model;

/// What the OBJ reader keeps beyond the mesh so the OBJ writer can restore it.
#[derive(Clone, Debug, Default)]
pub struct ObjExtras {}

/// Reads an OBJ file and its MTL libraries.
pub fn read(path: &Path) -> Result<Model, IoError> {
    Err(IoError::unsupported(path, "OBJ reader not written yet"))
}

/// Writes `model` as OBJ plus an MTL beside it.
pub fn write(_model: &Model, path: &Path, _opts: &WriteOptions) -> Result<(), IoError> {
    Err(IoError::unsupported(path, "OBJ writer not written yet"))
}

//! PLY (ascii, binary little and big endian) reader and writer.

use std::path::Path;

use super::{IoError, WriteOptions};
use crate::model::Model;

/// What the PLY reader keeps beyond the mesh (comments, for instance).
#[derive(Clone, Debug, Default)]
pub struct PlyExtras {}

/// Reads a PLY file.
pub fn read(path: &Path) -> Result<Model, IoError> {
    Err(IoError::unsupported(path, "PLY reader not written yet"))
}

/// Writes `model` as binary little-endian PLY with per-face texcoords.
pub fn write(_model: &Model, path: &Path, _opts: &WriteOptions) -> Result<(), IoError> {
    Err(IoError::unsupported(path, "PLY writer not written yet"))
}

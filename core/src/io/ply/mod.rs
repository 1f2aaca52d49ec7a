//! PLY (ascii, binary little and big endian) reader and writer, hand-written: the file is
//! memory-mapped and parsed in one pass, and MeshLab's texture conventions (`comment TextureFile`,
//! per-face `texcoord` and `texnumber`) are understood both ways.
//!
//! Reading: any elements in any order (unknown ones and unknown properties are skipped by their
//! declared types), every scalar type name and alias, per-vertex positions (any numeric type, to
//! f64), normals and UVs (`s,t`, `u,v`, `texture_u,texture_v`, `texture_s,texture_t`), faces by
//! `vertex_indices` or `vertex_index`, polygons triangulated in place (see `io::triangulate`).
//! Per-face texcoords win over per-vertex UVs. See [`read`] for the UV layout and the error policy.
//!
//! Writing: binary little endian by default (ascii on request), positions as `double` so
//! georeferenced coordinates survive exactly, MeshLab-compatible texture properties.

mod header;
mod read;
mod source;
mod write;

#[cfg(test)]
mod tests;

use std::path::Path;

use super::{IoError, WriteOptions};
use crate::model::Model;

/// The three PLY body encodings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PlyFormat {
    Ascii,
    #[default]
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// What the PLY reader keeps beyond the mesh, so writing back preserves the file's annotations.
#[derive(Clone, Debug, Default)]
pub struct PlyExtras {
    /// The body encoding of the file that was read.
    pub format: PlyFormat,
    /// `comment` lines, without the keyword, except MeshLab's `TextureFile` ones (those become
    /// sheets and are written afresh).
    pub comments: Vec<String>,
    /// `obj_info` lines, without the keyword.
    pub obj_info: Vec<String>,
    /// Elements and properties that were read past and dropped (e.g. `vertex property red`),
    /// for reports.
    pub skipped: Vec<String>,
}

/// Reads a PLY file.
///
/// The model gets one position per `vertex` (normals and per-vertex UVs indexed the same way),
/// one material and one sheet per `comment TextureFile` (resolved beside the PLY, material named
/// after the file stem), and faces in input order. Each face's material comes from `texnumber`
/// (`-1` means untextured; other values outside the sheets are an error naming the face), or is
/// the first sheet when the property is absent. Per-face `texcoord` lists add one UV record per
/// corner in face order; duplicates are not merged (a later stage welds them).
///
/// Malformed input is refused with an [`IoError`] naming the file and the header line, body line
/// (ascii) or byte offset (binary). A header declaring more elements than the file could hold
/// fails before any allocation.
pub fn read(path: &Path) -> Result<Model, IoError> {
    let file = crate::io::paths::open_regular(path).map_err(|e| IoError::file(path, e))?;
    let len = file.metadata().map_err(|e| IoError::file(path, e))?.len();
    if len == 0 {
        return Err(IoError::invalid(path, "empty file"));
    }
    // SAFETY: the map is read-only and lives only for this call. Like every memory-mapped reader,
    // this relies on no other process truncating or rewriting the input while it is read; the
    // tool never writes its inputs (outputs are atomic renames onto other paths).
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| IoError::file(path, e))?;
    #[cfg(unix)]
    {
        // Only a hint: failure changes nothing but speed.
        let _ = map.advise(memmap2::Advice::Sequential);
    }
    let header = header::parse(path, &map)?;
    read::read_body(path, &map, header)
}

/// Writes `model` as binary little-endian PLY (see [`write_with`]).
pub fn write(model: &Model, path: &Path, opts: &WriteOptions) -> Result<(), IoError> {
    write_with(model, path, opts, false)
}

/// Writes `model` as PLY, ascii when `ascii` is true, binary little endian otherwise.
///
/// Vertices carry `x y z` as `double` (exact for georeferenced scans) and `nx ny nz` as `float`
/// when the model has normals (per-vertex: a vertex takes the normal of its first corner). Faces
/// carry `vertex_indices` (uchar, int), and when the model has UVs a MeshLab-style `texcoord`
/// list (uchar, float; 6 values, or 0 for a face without UVs), and when it has sheets a
/// `texnumber` (int; -1 for a face without a sheet) with one `comment TextureFile` per sheet,
/// relative to the output directory. Embedded images are first written beside the output.
/// Every file is written atomically and no path in `opts.protect` is overwritten.
pub fn write_with(
    model: &Model,
    path: &Path,
    opts: &WriteOptions,
    ascii: bool,
) -> Result<(), IoError> {
    write::write(model, path, opts, ascii)
}

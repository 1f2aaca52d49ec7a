//! Wavefront OBJ + MTL reader and writer.
//!
//! The reader memory-maps the OBJ and parses it in two parallel passes over line-aligned chunks
//! (count, then parse straight into the final arrays), so it holds the model once and keeps
//! exact input order; see [`read`]. The writer streams the OBJ, its MTL and any embedded sheet
//! images through atomic files; see [`write`].

mod chunk;
mod lex;
mod mtl;
mod read;
mod write;

#[cfg(test)]
mod tests;

pub use read::read;
pub use write::write;

use crate::index::FaceId;

/// The kind of an OBJ grouping statement kept for the writer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroupKind {
    /// `g name...`
    Group,
    /// `o name`
    Object,
    /// `s 1` / `s off`
    Smoothing,
}

impl GroupKind {
    /// The OBJ keyword.
    pub fn keyword(self) -> &'static str {
        match self {
            Self::Group => "g",
            Self::Object => "o",
            Self::Smoothing => "s",
        }
    }
}

/// A `g`, `o` or `s` statement and the first face it precedes (`face` may equal the face count
/// when the statement came after the last face).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GroupMarker {
    pub kind: GroupKind,
    /// The rest of the statement's line, trimmed.
    pub name: String,
    pub face: FaceId,
}

/// What the OBJ reader keeps beyond the mesh so the OBJ writer can restore it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjExtras {
    /// Grouping statements in file order.
    pub groups: Vec<GroupMarker>,
    /// `(material name, options)` for each `map_Kd` that carried options (`-s 1 1 1`, ...).
    pub map_kd_options: Vec<(String, String)>,
    /// The material libraries (`mtllib`) read, resolved.
    pub libraries: Vec<std::path::PathBuf>,
}

/// The file a texture-map statement of a material (`map_Bump -bm 1 n.png`, stored resolved)
/// names; `None` for other statements.
pub fn map_file(line: &str) -> Option<std::path::PathBuf> {
    let (kw, rest) = lex::split_keyword(line.as_bytes());
    let kw = String::from_utf8_lossy(kw).to_ascii_lowercase();
    if !mtl::is_map_keyword(&kw) {
        return None;
    }
    let (_, file) = mtl::split_map_args(rest);
    (!file.is_empty()).then(|| std::path::PathBuf::from(file))
}

//! The photo atlas: the algorithms of the `build` command, which makes a texture atlas from
//! registered photographs (Velho & Sossai, "Projective texture atlas construction for 3D
//! photography"): cameras (COLMAP, Bundler), visibility, the variational distortion-based
//! partition, exposure gains, seam placement, the frequency analysis and frequency-based chart
//! splitting (Laplacian pyramids), the fill of unseen faces, colour smoothing and the Table 1
//! efficiencies. The stages that order them (packing, texturing, output) live in
//! [`crate::pipeline::build`].

pub mod bundler;
pub mod cameras;
pub mod colmap;
pub mod efficiency;
pub mod exposure;
pub mod fill;
pub mod frequency;
pub mod frequency_split;
pub mod occlusion;
pub mod partition;
pub mod photo_ring;
pub mod pyramid;
pub mod seam_placement;
pub mod seam_smoothing;
pub mod smoothing;
pub mod split;
pub mod visibility;

#[cfg(test)]
mod frequency_tests;
#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

pub use cameras::{Distortion, Intrinsics, PhotoCamera, Rig};

/// Errors of reading cameras and of the build stages.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error("{path}: {source}")]
    File { path: PathBuf, source: std::io::Error },
    /// A text file is malformed at a known line (1-based).
    #[error("{path}:{line}: {msg}")]
    Line { path: PathBuf, line: u64, msg: String },
    /// A binary file is malformed at a known byte offset.
    #[error("{path}: at byte {offset}: {msg}")]
    Byte { path: PathBuf, offset: u64, msg: String },
    #[error(
        "{path}:{line}: unknown camera model `{model}` (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV)"
    )]
    UnknownModel { path: PathBuf, line: u64, model: String },
    #[error("image `{name}` of camera {camera} not found in {dir}")]
    MissingImage { name: String, camera: usize, dir: PathBuf },
    #[error(
        "{path}: not a COLMAP model folder (cameras.txt/images.txt or cameras.bin/images.bin) nor a Bundler bundle.out"
    )]
    UnknownCameras { path: PathBuf },
    #[error("{0}")]
    Invalid(String),
}

impl BuildError {
    pub(crate) fn line(path: &Path, line: usize, msg: impl Into<String>) -> Self {
        Self::Line { path: path.to_path_buf(), line: line as u64, msg: msg.into() }
    }
    pub(crate) fn byte(path: &Path, offset: usize, msg: impl Into<String>) -> Self {
        Self::Byte { path: path.to_path_buf(), offset: offset as u64, msg: msg.into() }
    }
    pub(crate) fn file(path: &Path, source: std::io::Error) -> Self {
        Self::File { path: path.to_path_buf(), source }
    }
}

/// Reads a camera rig: `path` is a COLMAP sparse model folder (text preferred over binary when
/// both exist), a `bundle.out` file (with `list.txt` beside it), or a folder holding one.
/// Bundler stores no image sizes, so they are probed from the photos under `images`.
pub fn read_rig(path: &Path, images: &Path) -> Result<Rig, BuildError> {
    if path.is_dir() {
        if path.join("cameras.txt").is_file() && path.join("images.txt").is_file() {
            return colmap::read_text(path);
        }
        if path.join("cameras.bin").is_file() && path.join("images.bin").is_file() {
            return colmap::read_binary(path);
        }
        if path.join("bundle.out").is_file() {
            return bundler::read(&path.join("bundle.out"), images);
        }
    } else if path.is_file() {
        return bundler::read(path, images);
    }
    Err(BuildError::UnknownCameras { path: path.to_path_buf() })
}

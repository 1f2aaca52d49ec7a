//! Streaming encoders that write a `TileStore` as PNG (by rows), JPEG (by rows), tiled TIFF
//! (BigTIFF past 4 GiB) or tiled OpenEXR, atomically.

use std::path::{Path, PathBuf};

use super::{ImageFormat, TextureError, TileStore};

/// Options of the sheet writers.
#[derive(Clone, Debug)]
pub struct EncodeOptions {
    /// Output format; `None` = from the path's extension.
    pub format: Option<ImageFormat>,
    /// JPEG quality 1..=100.
    pub jpeg_quality: u8,
    /// Paths that must never be overwritten.
    pub protect: Vec<PathBuf>,
}

impl Default for EncodeOptions {
    fn default() -> Self {
        Self { format: None, jpeg_quality: 90, protect: Vec::new() }
    }
}

/// Writes `store` to `path`, atomically.
pub fn write_image(
    store: &TileStore,
    path: &Path,
    opts: &EncodeOptions,
) -> Result<(), TextureError> {
    let _ = (store, opts);
    Err(TextureError::Encode { path: path.to_path_buf(), msg: "not written yet".into() })
}

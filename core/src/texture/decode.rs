//! Decoders that fill a `TileStore` from PNG, JPEG, TIFF and OpenEXR without holding the whole
//! decoded image in memory (except JPEG; see `decode_to_store`).

use std::path::Path;

use super::{TextureError, TileStore};
use crate::model::ImageSource;

/// Width and height of an image, read from its header only.
pub fn probe_size(src: &ImageSource) -> Result<(u32, u32), TextureError> {
    Err(TextureError::Unsupported { image: src.describe(), msg: "not written yet".into() })
}

/// Decodes an image into a new `TileStore` under `work_dir`.
pub fn decode_to_store(src: &ImageSource, work_dir: &Path) -> Result<TileStore, TextureError> {
    let _ = work_dir;
    Err(TextureError::Unsupported { image: src.describe(), msg: "not written yet".into() })
}


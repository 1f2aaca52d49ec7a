//! Decoders that fill a `TileStore` from PNG, JPEG, TIFF, OpenEXR and WebP without holding the
//! whole decoded image in memory (WebP excepted: see its codec).
//!
//! The format is recognised from the file's first bytes, never from its extension or declared
//! MIME type. PNG is read row by row (interlaced images too), TIFF strip by strip or tile by tile
//! (classic and BigTIFF), OpenEXR block by block (scanline and tiled), JPEG in strips of
//! scanlines through mozjpeg. The one exception is a build without the `mozjpeg` feature, where
//! JPEG is decoded whole by zune-jpeg under a size limit ([`DEFAULT_JPEG_MAX_MPIX`], overridable
//! with the environment variable [`JPEG_MAX_MPIX_ENV`]).
//!
//! Every failure is a [`TextureError`] naming the image: zero sizes, truncated data, kinds we do
//! not read (BMP, GIF, WebP... are named), and headers claiming more pixels than the file could
//! encode, which are refused before anything is allocated.

use std::path::Path;

use super::codec::{self, Opened};
use super::{ImageFormat, TextureError, TileStore};
use crate::model::ImageSource;

pub use super::codec::jpeg::{DEFAULT_JPEG_MAX_MPIX, JPEG_MAX_MPIX_ENV, jpeg_max_mpix};
pub use super::codec::tiff::MAX_CHUNK_BYTES as TIFF_MAX_CHUNK_BYTES;

/// Opens `src` and recognises its format from the magic bytes.
fn open_detect(src: &ImageSource) -> Result<(Opened<'_>, ImageFormat), TextureError> {
    let op = codec::open(src)?;
    if op.len == 0 {
        return Err(TextureError::Decode { image: op.name, msg: "empty file".into() });
    }
    match ImageFormat::from_magic(&op.head) {
        Some(f) => Ok((op, f)),
        None => {
            let msg = match codec::other_kind(&op.head) {
                Some(kind) => {
                    format!(
                        "{kind} images are not supported (use PNG, JPEG, TIFF, OpenEXR or WebP)"
                    )
                }
                // The file's bytes are never quoted: a reference may point at a private file.
                None => "not a PNG, JPEG, TIFF, OpenEXR or WebP file".to_string(),
            };
            Err(TextureError::Unsupported { image: op.name, msg })
        }
    }
}

/// Width and height of an image, read from its header only.
pub fn probe_size(src: &ImageSource) -> Result<(u32, u32), TextureError> {
    let (op, format) = open_detect(src)?;
    let name = op.name.clone();
    let (w, h) = match format {
        ImageFormat::Png => codec::png::probe(op)?,
        ImageFormat::Jpeg => codec::jpeg::probe(op)?,
        ImageFormat::Tiff => codec::tiff::probe(op)?,
        ImageFormat::Exr => codec::exr::probe(op)?,
        ImageFormat::Webp => codec::webp::probe(op)?,
    };
    if w == 0 || h == 0 {
        return Err(TextureError::Size {
            image: name,
            width: w as u64,
            height: h as u64,
            msg: "zero-sized image".into(),
        });
    }
    Ok((w, h))
}

/// Decodes an image into a new `TileStore` under `work_dir`, keeping its channels (1 gray,
/// 2 gray+alpha, 3 RGB, 4 RGBA) and bit depth (8 and 16 bits stay `U8`/`U16`; OpenEXR and float
/// TIFF become `F32`). Palette PNGs are expanded; CMYK JPEGs become RGB.
pub fn decode_to_store(src: &ImageSource, work_dir: &Path) -> Result<TileStore, TextureError> {
    let (op, format) = open_detect(src)?;
    let name = op.name.clone();
    let store = match format {
        ImageFormat::Png => codec::png::decode(op, work_dir),
        ImageFormat::Jpeg => codec::jpeg::decode(op, work_dir),
        ImageFormat::Tiff => codec::tiff::decode(op, work_dir),
        ImageFormat::Exr => codec::exr::decode(op, work_dir),
        ImageFormat::Webp => codec::webp::decode(op, work_dir),
    };
    // The store reports its own size errors as "tile store"; name the image instead.
    store.map_err(|e| match e {
        TextureError::Size { image, width, height, msg } if image == "tile store" => {
            TextureError::Size { image: name, width, height, msg }
        }
        other => other,
    })
}

//! Streaming encoders that write a `TileStore` as PNG (by rows), JPEG (by rows), tiled TIFF
//! (BigTIFF past 4 GiB), tiled OpenEXR, or WebP (whole image, see the WebP codec), atomically.
//!
//! Every writer goes through [`AtomicFile`]: the image is written under a temporary name beside
//! the target and renamed into place only when complete, so an error leaves neither a partial
//! file nor a stray temporary, and a protected path (an input) is never overwritten.
//!
//! What each format keeps: PNG keeps 8/16 bits and 1–4 channels (f32 stores are refused); TIFF
//! keeps everything (8/16-bit, f32, 1–4 channels); OpenEXR is written as f32 (u8/u16 stores
//! are scaled to 0..1); JPEG is 8-bit gray or YCbCr, alpha dropped (see the JPEG codec).

use std::io::Write;
use std::path::{Path, PathBuf};

use super::codec;
use super::{ImageFormat, TextureError, TileStore};
use crate::atomic::AtomicFile;

/// Options of the sheet writers.
#[derive(Clone, Debug)]
pub struct EncodeOptions {
    /// Output format; `None` = from the path's extension.
    pub format: Option<ImageFormat>,
    /// JPEG quality 1..=100.
    pub jpeg_quality: u8,
    /// WebP: `None` lossless, `Some(q)` lossy at quality `q` (1..=100).
    pub webp_quality: Option<u8>,
    /// Paths that must never be overwritten.
    pub protect: Vec<PathBuf>,
}

impl Default for EncodeOptions {
    fn default() -> Self {
        Self { format: None, jpeg_quality: 90, webp_quality: None, protect: Vec::new() }
    }
}

/// Writes `store` to `path`, atomically.
pub fn write_image(
    store: &TileStore,
    path: &Path,
    opts: &EncodeOptions,
) -> Result<(), TextureError> {
    let enc_err = |msg: String| TextureError::Encode { path: path.to_path_buf(), msg };
    let file_err = |e: std::io::Error| TextureError::File { path: path.to_path_buf(), source: e };
    let format = opts.format.or_else(|| ImageFormat::from_path(path)).ok_or_else(|| {
        enc_err("no output format given and the extension is not png, jpg, tif, exr or webp".into())
    })?;
    // Checks that need no file come first, so a refusal creates nothing.
    if format == ImageFormat::Jpeg && (store.width() > 65535 || store.height() > 65535) {
        return Err(TextureError::Size {
            image: path.display().to_string(),
            width: store.width() as u64,
            height: store.height() as u64,
            msg: "JPEG cannot exceed 65535 pixels per side".into(),
        });
    }
    if format == ImageFormat::Webp {
        codec::webp::check_size(store).map_err(|msg| TextureError::Size {
            image: path.display().to_string(),
            width: store.width() as u64,
            height: store.height() as u64,
            msg,
        })?;
    }
    let mut file = AtomicFile::create(path, &opts.protect).map_err(file_err)?;
    {
        let mut w = file.writer();
        match format {
            ImageFormat::Png => codec::png::encode(store, &mut w),
            ImageFormat::Jpeg => codec::jpeg::encode(store, &mut w, opts.jpeg_quality),
            ImageFormat::Tiff => codec::tiff::encode(store, &mut w),
            ImageFormat::Exr => codec::exr::encode(store, &mut w),
            ImageFormat::Webp => codec::webp::encode(store, &mut w, opts.webp_quality),
        }
        .map_err(enc_err)?;
        w.flush().map_err(file_err)?;
    }
    file.commit().map_err(file_err)
}

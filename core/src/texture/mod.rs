//! Textures out of core: the texel convention, the memory-mapped tiled pixel store, decoders that
//! fill it by rows, strips or tiles, streaming encoders, and the triangle rasterizer.
//!
//! Architecture invariant: no function here holds a whole decoded sheet in RAM, except the JPEG
//! decoder of a build without the `mozjpeg` feature, whose limit is documented on [`decode`].

mod codec;
pub mod coords;
pub mod decode;
pub mod encode;
pub mod gutter;
pub mod raster;
pub mod resample;
pub mod store;
pub mod work_usage;

use std::path::PathBuf;

pub use coords::{pixel_of_texel, texel_center};
pub use store::TileStore;

/// Errors of texture reading, tiling and writing.
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    /// The operating system refused an operation on a file.
    #[error("{path}: {source}")]
    File { path: PathBuf, source: std::io::Error },
    /// The image could not be decoded.
    #[error("{image}: cannot decode: {msg}")]
    Decode { image: String, msg: String },
    /// The image could not be encoded or written.
    #[error("{path}: cannot encode: {msg}")]
    Encode { path: PathBuf, msg: String },
    /// An image kind scanatlas does not handle (named in `msg`).
    #[error("{image}: unsupported image: {msg}")]
    Unsupported { image: String, msg: String },
    /// Width or height zero, or too large for the format or the address space.
    #[error("{image}: invalid size {width}x{height}: {msg}")]
    Size { image: String, width: u64, height: u64, msg: String },
    /// A texture mapping (faces, sheets, options) that cannot be resampled.
    #[error("texture resampling: {msg}")]
    Mapping { msg: String },
}

/// The type of one sample (one channel of one pixel).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SampleType {
    U8,
    U16,
    F32,
}

impl SampleType {
    /// Bytes per sample.
    pub fn bytes(self) -> usize {
        match self {
            Self::U8 => 1,
            Self::U16 => 2,
            Self::F32 => 4,
        }
    }
}

/// Channels (1 gray, 2 gray+alpha, 3 RGB, 4 RGBA) and sample type of a pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct PixelFormat {
    pub channels: u8,
    pub sample: SampleType,
}

impl PixelFormat {
    pub const RGB8: Self = Self { channels: 3, sample: SampleType::U8 };
    pub const RGBA8: Self = Self { channels: 4, sample: SampleType::U8 };

    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> usize {
        self.channels as usize * self.sample.bytes()
    }
}

/// Image file formats scanatlas reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ImageFormat {
    Png,
    Jpeg,
    Tiff,
    Exr,
    Webp,
}

impl ImageFormat {
    /// The format a path's extension names (case-insensitive).
    pub fn from_path(path: &std::path::Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "png" => Some(Self::Png),
            "jpg" | "jpeg" => Some(Self::Jpeg),
            "tif" | "tiff" => Some(Self::Tiff),
            "exr" => Some(Self::Exr),
            "webp" => Some(Self::Webp),
            _ => None,
        }
    }

    /// The format named by a MIME type (`image/png`, ...).
    pub fn from_mime(mime: &str) -> Option<Self> {
        match mime.to_ascii_lowercase().as_str() {
            "image/png" => Some(Self::Png),
            "image/jpeg" | "image/jpg" => Some(Self::Jpeg),
            "image/tiff" => Some(Self::Tiff),
            "image/x-exr" | "image/exr" => Some(Self::Exr),
            "image/webp" => Some(Self::Webp),
            _ => None,
        }
    }

    /// The format recognised from the first bytes of a file.
    pub fn from_magic(head: &[u8]) -> Option<Self> {
        if head.starts_with(b"\x89PNG\r\n\x1a\n") {
            Some(Self::Png)
        } else if head.starts_with(&[0xFF, 0xD8, 0xFF]) {
            Some(Self::Jpeg)
        } else if head.starts_with(b"II*\0")
            || head.starts_with(b"MM\0*")
            || head.starts_with(b"II+\0")
            || head.starts_with(b"MM\0+")
        {
            Some(Self::Tiff)
        } else if head.starts_with(&[0x76, 0x2F, 0x31, 0x01]) {
            Some(Self::Exr)
        } else if head.len() >= 12 && &head[..4] == b"RIFF" && &head[8..12] == b"WEBP" {
            Some(Self::Webp)
        } else {
            None
        }
    }

    /// The format of an image source, from its first bytes (never from its name, which may lie).
    pub fn of_source(src: &crate::model::ImageSource) -> Result<Self, TextureError> {
        use std::io::Read;
        let mut head = [0u8; 12];
        let n = match src {
            crate::model::ImageSource::File(path) => {
                let mut f = std::fs::File::open(path)
                    .map_err(|e| TextureError::File { path: path.clone(), source: e })?;
                f.read(&mut head)
                    .map_err(|e| TextureError::File { path: path.clone(), source: e })?
            }
            crate::model::ImageSource::Embedded { bytes, .. } => {
                let n = bytes.len().min(12);
                head[..n].copy_from_slice(&bytes[..n]);
                n
            }
        };
        Self::from_magic(&head[..n]).ok_or_else(|| TextureError::Unsupported {
            image: src.describe(),
            msg: "not a PNG, JPEG, TIFF, OpenEXR or WebP image".into(),
        })
    }

    /// The longest side the format can hold, when it is shorter than any sheet may be.
    pub fn max_side(self) -> Option<u32> {
        match self {
            Self::Webp => Some(codec::webp::MAX_SIDE),
            Self::Jpeg => Some(u32::from(u16::MAX)),
            Self::Png | Self::Tiff | Self::Exr => None,
        }
    }

    /// The canonical extension.
    pub fn extension(self) -> &'static str {
        match self {
            Self::Png => "png",
            Self::Jpeg => "jpg",
            Self::Tiff => "tif",
            Self::Exr => "exr",
            Self::Webp => "webp",
        }
    }
}

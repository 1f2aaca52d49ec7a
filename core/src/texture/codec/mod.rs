//! Per-format image codecs (PNG, JPEG, TIFF, OpenEXR, WebP) behind `decode` and `encode`, and what they
//! share: opening an `ImageSource` as a seekable buffered reader, recognising formats we do not
//! handle, refusing headers that claim more pixels than the file could hold, and turning a panic
//! inside a third-party decoder into an error.

pub(super) mod exr;
pub(super) mod jpeg;
pub(super) mod png;
pub(super) mod tiff;
pub(super) mod webp;

use std::fs::File;
use std::io::{self, BufRead, BufReader, Cursor, Read, Seek, SeekFrom};

use super::{SampleType, TextureError, TileStore};
use crate::model::ImageSource;

/// Capacity of the buffered file reader: big enough that decoders issue few system calls, small
/// enough to be irrelevant for memory.
const READ_BUFFER: usize = 256 * 1024;

/// An opened image: a buffered file or an in-memory embedded image, both `BufRead + Seek`.
pub(super) enum Input<'a> {
    File(BufReader<File>),
    Mem(Cursor<&'a [u8]>),
}

impl Read for Input<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Self::File(r) => r.read(buf),
            Self::Mem(r) => r.read(buf),
        }
    }
}

impl BufRead for Input<'_> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        match self {
            Self::File(r) => r.fill_buf(),
            Self::Mem(r) => r.fill_buf(),
        }
    }
    fn consume(&mut self, amt: usize) {
        match self {
            Self::File(r) => r.consume(amt),
            Self::Mem(r) => r.consume(amt),
        }
    }
}

impl Seek for Input<'_> {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        match self {
            Self::File(r) => r.seek(pos),
            Self::Mem(r) => r.seek(pos),
        }
    }
}

/// An opened image source with what every decoder needs to know about it.
pub(super) struct Opened<'a> {
    pub input: Input<'a>,
    /// Length of the encoded file in bytes.
    pub len: u64,
    /// The first bytes (up to 16), for format detection.
    pub head: Vec<u8>,
    /// The name used in error messages (the path or the embedded image's name).
    pub name: String,
}

/// Opens `src` for reading and peeks at its first bytes.
pub(super) fn open(src: &ImageSource) -> Result<Opened<'_>, TextureError> {
    let name = src.describe();
    match src {
        ImageSource::File(path) => {
            let file_err = |e| TextureError::File { path: path.clone(), source: e };
            let file = crate::io::paths::open_regular(path).map_err(file_err)?;
            let len = file.metadata().map_err(file_err)?.len();
            let mut input = BufReader::with_capacity(READ_BUFFER, file);
            let head = input.fill_buf().map_err(file_err)?;
            let head = head[..head.len().min(16)].to_vec();
            Ok(Opened { input: Input::File(input), len, head, name })
        }
        ImageSource::Embedded { bytes, .. } => {
            let data: &[u8] = bytes.as_slice();
            let head = data[..data.len().min(16)].to_vec();
            Ok(Opened { input: Input::Mem(Cursor::new(data)), len: data.len() as u64, head, name })
        }
    }
}

/// The kind of a file we recognise but do not decode, for the error message.
pub(super) fn other_kind(head: &[u8]) -> Option<&'static str> {
    let kinds: [(&[u8], &str); 11] = [
        (b"BM", "BMP"),
        (b"GIF87a", "GIF"),
        (b"GIF89a", "GIF"),
        (b"qoif", "QOI"),
        (b"DDS ", "DDS"),
        (b"8BPS", "Photoshop PSD"),
        (b"#?RADIANCE", "Radiance HDR"),
        (b"#?RGBE", "Radiance HDR"),
        (b"\xabKTX", "KTX"),
        (b"\0\0\0\x0cjP  ", "JPEG 2000"),
        (b"\xff\x4f\xff\x51", "JPEG 2000 codestream"),
    ];
    if let Some((_, kind)) = kinds.iter().find(|(magic, _)| head.starts_with(magic)) {
        return Some(kind);
    }
    if head.len() >= 12 && &head[4..8] == b"ftyp" {
        return Some(match &head[8..12] {
            b"avif" | b"avis" => "AVIF",
            b"heic" | b"heix" | b"mif1" | b"msf1" => "HEIF/HEIC",
            _ => "ISO media (MP4/HEIF family)",
        });
    }
    if head.starts_with(b"P1")
        || head.starts_with(b"P2")
        || head.starts_with(b"P3")
        || head.starts_with(b"P4")
        || head.starts_with(b"P5")
        || head.starts_with(b"P6")
    {
        return Some("PNM (PBM/PGM/PPM)");
    }
    None
}

/// The most pixels one byte of an encoded file can stand for, across the formats we read. The
/// tightest honest bound is deflate's ~1032:1 on 1-bit PNG rows (8 pixels per byte), about 8256
/// pixels per byte; JPEG's best case (an empty 8×8 block in about 2 bits) is ~256. A header
/// claiming more than this many pixels per file byte is lying, and is refused before anything
/// is allocated or mapped.
pub(super) const MAX_PIXELS_PER_FILE_BYTE: u64 = 16_384;

/// Refuses zero sizes and sizes the file cannot possibly encode (see [`MAX_PIXELS_PER_FILE_BYTE`]).
/// `max_pixels_per_byte` lets a format use a tighter bound.
pub(super) fn check_plausible(
    name: &str,
    width: u32,
    height: u32,
    file_len: u64,
    max_pixels_per_byte: u64,
) -> Result<(), TextureError> {
    let size_err = |msg: String| TextureError::Size {
        image: name.to_string(),
        width: width as u64,
        height: height as u64,
        msg,
    };
    if width == 0 || height == 0 {
        return Err(size_err("zero-sized image".into()));
    }
    let pixels = width as u64 * height as u64;
    // The slack covers headers and tiny images whose pixel data is smaller than their metadata.
    let max = (file_len + 4096).saturating_mul(max_pixels_per_byte);
    if pixels > max {
        return Err(size_err(format!(
            "the header claims {pixels} pixels but the file has only {file_len} bytes, which \
             cannot encode more than {max} pixels: the header is corrupt or the file truncated"
        )));
    }
    Ok(())
}

/// A decode error for image `name`.
pub(super) fn decode_err(name: &str, msg: impl Into<String>) -> TextureError {
    TextureError::Decode { image: name.to_string(), msg: msg.into() }
}

/// `Err` with the stop's message when a stop was asked for. The codecs call it once per row of
/// tiles, so a signal that arrives while a gigapixel sheet is decoded or encoded takes effect
/// within one tile row instead of after the whole image.
pub(super) fn stop_requested() -> Result<(), String> {
    crate::cancel::check().map_err(|e| e.to_string())
}

/// Runs `f`, turning a panic inside a third-party codec into a decode error: a malformed file
/// must never abort the program. mozjpeg reports every libjpeg error this way by design; for the
/// pure-Rust crates it is a last line of defence against their bugs.
pub(super) fn guard<T>(
    name: &str,
    f: impl FnOnce() -> Result<T, TextureError>,
) -> Result<T, TextureError> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let msg = payload
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "the decoder failed on malformed data".into());
            Err(decode_err(name, msg))
        }
    }
}

/// Copies a `width`-pixel rectangle of `rows` rows from `src` (row stride `src_stride` bytes)
/// into the store at `(x0, y0)`, row by row.
pub(super) fn blit(
    store: &mut TileStore,
    x0: u32,
    y0: u32,
    width: u32,
    rows: u32,
    src: &[u8],
    src_stride: usize,
) {
    let bpp = store.format().bytes_per_pixel();
    let n = width as usize * bpp;
    for r in 0..rows {
        let o = r as usize * src_stride;
        store.write_row(y0 + r, x0, &src[o..o + n]);
    }
}

/// Sample `i` of pixel data `px` as 8 bits: 16-bit samples rounded, float samples clamped to
/// 0..1 and scaled (no tone mapping), for the 8-bit-only formats (JPEG, WebP).
#[inline]
pub(super) fn sample8(px: &[u8], sample: SampleType, i: usize) -> u8 {
    match sample {
        SampleType::U8 => px[i],
        SampleType::U16 => {
            let v = u16::from_ne_bytes([px[2 * i], px[2 * i + 1]]) as u32;
            ((v * 255 + 32767) / 65535) as u8
        }
        SampleType::F32 => {
            let b = [px[4 * i], px[4 * i + 1], px[4 * i + 2], px[4 * i + 3]];
            let v = f32::from_ne_bytes(b);
            // NaN maps to 0 through the saturating cast.
            (v.clamp(0.0, 1.0) * 255.0).round() as u8
        }
    }
}

/// Converts 16-bit big-endian samples (PNG's order) to native-endian in place.
pub(super) fn be16_to_native(bytes: &mut [u8]) {
    if cfg!(target_endian = "little") {
        for pair in bytes.chunks_exact_mut(2) {
            pair.swap(0, 1);
        }
    }
}

#[cfg(test)]
mod tests;
